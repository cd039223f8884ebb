"""Writing files safely: atomic writes, output checks, result sets and their manifests.

**Files.** Every file vsj writes goes through `atomic_write`: it is written to
a temporary file that replaces the target only when complete, so a failed or
interrupted write never leaves a half file where a good one stood. On Linux the
temporary file has no name while it is written (``O_TMPFILE``), so a process
killed meanwhile leaves nothing behind; elsewhere it is a hidden
``.NAME.vsj-tmp-XXXX`` beside the target.

**Result sets.** A command that writes several files into a directory (``vsj
simulate``, ``reproduce``, ``datasheet``, ``fit``, ``synth stiffness``) writes
them as one `ResultSet`, which

1. checks the directory before any work is done (`OutputError`, exit code 2,
   naming the option and the path): not an existing file, creatable, writable,
   enough free space for a conservative estimate of the results, and holding
   nothing but files vsj wrote, as its manifest records them (vsj never replaces
   or removes a file it did not write, whatever its name);
2. takes an exclusive lock on the directory (``flock``) and refuses a second
   writer; the kernel drops the lock when its holder dies, so none goes stale;
3. has the new files written into a hidden staging directory beside the
   target, on the same file system;
4. commits by exchanging the staging directory with the target in one step
   (Linux ``renameat2(RENAME_EXCHANGE)``): readers see either the complete old
   set or the complete new set, never a mixture; then removes the old set.

Several sets can share a directory (``vsj simulate`` and ``vsj datasheet``
both default to ``out``; ``fit friction`` writes one set per data file): the
files of the other sets are carried into the new directory as hard links. The
directory's ``vsj-manifest.json`` lists every set with the SHA-256 of each of
its files; `verify` (``vsj verify DIR``) checks them.

A small watchdog process (started per set, holding the lock with it) removes
the staging directory if vsj is killed, so a killed run leaves neither hidden
files nor, on a first run, an empty output directory; if the watchdog is
killed too, the next writer of that directory removes the leftovers under the
lock.

Where the exchange is impossible (the directory is a mount point, or the
current directory of this process, or on a file system without
``RENAME_EXCHANGE``), the set is replaced *in place*: the new files are
renamed over the old ones one by one. That is weaker: a process killed in the
middle leaves a mixed set, which the manifest marks incomplete and whose
hashes no longer match, so `verify` names it; it is never silently taken for
a good one.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import functools
import hashlib
import json
import linecache
import math
import os
import re
import secrets
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Self

import numpy as np

from .. import __version__
from ..errors import InputError, read_bytes

#: The manifest of an output directory: every result set in it, with its files' hashes.
MANIFEST = "vsj-manifest.json"

#: The files each kind of result set may hold (regular expressions of file names).
#: A file is vsj's only if a directory's manifest records it: whatever its name, vsj
#: never replaces or removes any other.
OUTPUTS = {
    "simulate": r"trajectory\.(?:nc|csv|png)|meta\.json",
    "reproduce": r"fig-\d+\.\d+(?:-[a-z]+)?\.(?:png|svg|npz)|results\.json|report\.html",
    "datasheet": r"datasheet\.(?:html|json)",
    "fit friction": r"[^/]+-friction\.(?:json|png)",
    "fit planetary": r"planetary\.(?:json|png)",
    "fit stiffness": r"stiffness\.(?:json|png)|geometry\.png",
    "msl": r"msl-[a-z-]+\.(?:nc|png|json)",
    "synth stiffness": r"stiffness_q[+-]\d+\.\dcm\.csv",
    "fit wrist": r"wrist-fit\.(?:json|html)|wrist-(?:fit|validation)\.png",
    "sweep": r"sweep\.json|metrics\.csv|sensitivity\.csv|summary\.html|sweep-[\w.-]+\.png",
    "study": r"(?:tracking-safety|impact-speed|(?:study-)?(?:safe-and-fast|explosive-motion))"
             r"\.(?:png|svg|json|html)",
}

_ANY_OUTPUT = "|".join(f"(?:{p})" for p in OUTPUTS.values())
_VSJ_FILE = rf"(?:{_ANY_OUTPUT})|{re.escape(MANIFEST)}"
#: The name of the files that try whether a directory is writable and takes unnamed files
#: (`_anonymous_files_work`): removed at once, but left by a process killed meanwhile.
PROBE = "probe"
#: What `clear_staging` may delete: vsj's files and `atomic_write`'s temporaries of them.
_DISPOSABLE = rf"{_VSJ_FILE}|\.(?:{_VSJ_FILE}|{PROBE})\.vsj-tmp-\w+"
_TEMPORARY = re.compile(rf"\.(?:{_VSJ_FILE}|{PROBE})\.vsj-tmp-\w+")
_IN_PLACE_STAGING = re.compile(r"\.vsj-[0-9a-f]{16}")


#: A conservative bound on the bytes of a command's small outputs (a parameter file, a
#: model, a fit's JSON and plots: each well under a megabyte), for the free-space check.
SMALL_OUTPUT_BYTES = 16 * 2 ** 20


class OutputError(InputError):
    """An output path vsj cannot write (exit code 2); the message names the option and
    the path, and says that nothing there was changed."""


# --- single files -------------------------------------------------------------------

_AT_FDCWD = -100
_AT_EMPTY_PATH = 0x1000
_RENAME_EXCHANGE = 2


@functools.cache
def _libc():
    return ctypes.CDLL(None, use_errno=True)


def _link(fd: int, dest: Path) -> None:
    """Give the open file ``fd`` (an ``O_TMPFILE``) the name ``dest``."""
    try:
        os.link(f"/proc/self/fd/{fd}", dest, follow_symlinks=True)
        return
    except OSError:  # no /proc, or one that will not link (some sandboxes)
        pass
    try:
        linkat = _libc().linkat
    except (OSError, AttributeError):
        raise OSError(errno.ENOSYS, "cannot link an anonymous file", str(dest)) from None
    if linkat(fd, b"", _AT_FDCWD, os.fsencode(dest), _AT_EMPTY_PATH) != 0:
        code = ctypes.get_errno()
        raise OSError(code, os.strerror(code), str(dest))


def _temp_name(name: str) -> str:
    return f".{name}.vsj-tmp-{secrets.token_hex(4)}"


def _anonymous_files_work(directory: Path) -> bool:
    """Whether ``directory`` takes unnamed files that can be linked in later (tried on a
    probe: ``O_TMPFILE`` needs Linux and a file system that has it)."""
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None:
        return False
    try:
        fd = os.open(directory, flag | os.O_WRONLY | os.O_CLOEXEC, 0o600)
    except OSError:
        return False
    probe = directory / _temp_name(PROBE)
    try:
        _link(fd, probe)
        os.unlink(probe)
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def _temporary_file(directory: Path, name: str) -> tuple[int, Path | None]:
    """An open temporary file in ``directory`` for the file ``name`` (for reading and
    writing): unnamed where the file system allows (then ``None``), else a hidden file
    with its path."""
    if _anonymous_files_work(directory):
        return os.open(directory, os.O_TMPFILE | os.O_RDWR | os.O_CLOEXEC, 0o666), None
    fd, temp = tempfile.mkstemp(prefix=f".{name}.vsj-tmp-", dir=directory)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temp, 0o666 & ~umask)  # mkstemp makes it private; results are ordinary files
    return fd, Path(temp)


_SYNC_FILE_RANGE_WRITE = 2


def start_writeback(fd: int) -> None:
    """Have the kernel start writing the data of the open file ``fd`` to disk, without
    waiting for it (Linux ``sync_file_range``; elsewhere nothing). A large file written
    in parts while other work goes on is then mostly on disk by the time `atomic_write`
    syncs it, and that sync waits for the rest only."""
    try:
        begin = _libc().sync_file_range
    except (OSError, AttributeError):
        return
    begin.argtypes = [ctypes.c_int, ctypes.c_int64, ctypes.c_int64, ctypes.c_uint]
    begin(fd, 0, 0, _SYNC_FILE_RANGE_WRITE)  # a hint: a failure leaves the sync all to do


def _sync_during(fd: int, work) -> None:
    """``os.fsync(fd)`` in another thread while ``work(fd)`` runs in this one (both wait
    outside Python's lock: on the disk, and in reading and hashing)."""
    failed = []

    def sync():
        try:
            os.fsync(fd)
        except OSError as exc:
            failed.append(exc)

    syncer = threading.Thread(target=sync, name="vsj-fsync")
    syncer.start()
    try:
        work(fd)
    finally:
        syncer.join()
    if failed:
        raise failed[0]


@contextlib.contextmanager
def atomic_write(path: Path, mode: str = "w", *, when_complete=None):
    """Write ``path`` through a temporary file that replaces it on success (see the
    module docstring); the data is on disk (``fsync``) before the rename. ``mode`` is
    ``"w"``, ``"wb"``, or ``"w+b"`` to read back what was written.
    ``when_complete(fd)``, if given, is called with the descriptor of the complete file
    while the sync runs (`ResultSet.write` hashes it then)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, named = _temporary_file(path.parent, path.name)
    temp = named or path.parent / _temp_name(path.name)
    linked = named is not None
    try:
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8",
                       newline="" if "b" not in mode else None) as handle:
            yield handle
            handle.flush()
            if when_complete is None:
                os.fsync(handle.fileno())
            else:
                _sync_during(handle.fileno(), when_complete)
            if not linked:
                _link(handle.fileno(), temp)
                linked = True
        os.replace(temp, path)
    except BaseException as exc:
        if linked:
            with contextlib.suppress(OSError):
                os.unlink(temp)
        if isinstance(exc, OSError) and exc.filename is None:
            exc.filename = str(path)  # a failed write() names no file
        raise


def _nearest_existing(path: Path) -> Path:
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _megabytes(size: float) -> str:
    return f"{size / 1e6:.3g} MB"


def _check_space(directory: Path, size: int, shown: str) -> None:
    if size <= 0:
        return
    info = os.statvfs(directory)
    free = info.f_bavail * info.f_frsize
    if size > free:
        raise OutputError(f"{shown}: the results need up to {_megabytes(size)} (a conservative "
                          f"estimate), but its file system has {_megabytes(free)} free; nothing "
                          "was written")


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


#: How much of an existing file `written_by_vsj` reads to recognise it.
_SNIFF_BYTES = 64 * 1024


def written_by_vsj(path: str | Path) -> bool:
    """Whether the existing file ``path`` carries vsj's mark: a model file of the C
    engine (``VSJP``/``VSJM``), an FMU whose
    modelDescription.xml names vsj as its generation tool, a JSON document with a
    ``vsj`` or ``vsj_version`` key (or a ``format`` that starts with ``vsj``), or a text
    file (TOML, CSV) whose comment lines at the top name vsj. Unreadable or other files
    are not vsj's."""
    import zipfile  # lazy: only an FMU among the files vsj writes is a zip archive

    path = Path(path)
    try:
        with open(path, "rb") as handle:
            head = handle.read(_SNIFF_BYTES)
            if head.startswith((b"VSJP", b"VSJM")):  # a model file (vsj.export)
                return True
            if head.startswith(b"PK"):
                handle.seek(0)
                with zipfile.ZipFile(handle) as archive:
                    if "modelDescription.xml" in archive.namelist():
                        xml = archive.read("modelDescription.xml")[:_SNIFF_BYTES]
                        return re.search(rb'generationTool="vsj[ "]', xml) is not None
                    return "vsj_version.npy" in archive.namelist()
            if head.lstrip().startswith(b"{"):
                handle.seek(0)
                document = json.loads(handle.read(SMALL_OUTPUT_BYTES).decode("utf-8"))
                return isinstance(document, dict) and (
                    "vsj" in document or "vsj_version" in document
                    or str(document.get("format", "")).startswith("vsj"))
    except (OSError, ValueError, zipfile.BadZipFile, UnicodeDecodeError):
        return False
    for line in head.decode("utf-8", errors="replace").splitlines():
        if not line.startswith("#"):  # the comments at the top only
            return False
        if re.search(r"\bvsj\b", line):
            return True
    return False


def check_output_file(path: str | Path, option: str, *, size: int = 0,
                      force: bool = False, forceable: bool = True) -> Path:
    """`OutputError` unless a file can be written at ``path`` (checked before the work that
    produces it): not a directory, not an existing file that vsj did not write (unless
    ``force``: `written_by_vsj`) nor a file of a result set in its directory, its
    directory creatable and writable (tried with a temporary file that leaves nothing
    behind), and ``size`` bytes free. The messages offer ``--force`` where the command
    has it (``forceable``). Writes nothing."""
    path = Path(path)
    shown = f"{option} {path}"
    remedy = "choose another name, or give --force to replace it" if forceable else \
        "choose another name or directory"
    if path.is_dir():
        raise OutputError(f"{shown}: is a directory; give the name of a file")
    if path.name in ("", ".", ".."):
        raise OutputError(f"{shown}: give the name of a file")
    if not force and (path.exists() or path.is_symlink()):
        if not path.is_file():
            raise OutputError(f"{shown}: exists and is not a regular file; vsj replaces only "
                              "files it wrote")
        in_set = [name for name, entry in read_manifest(path.parent)["sets"].items()
                  if path.name in entry.get("files", {})] if path.name != MANIFEST else [""]
        if in_set:
            what = f"a file of the result set {in_set[0]!r}" if in_set[0] else "the manifest"
            raise OutputError(f"{shown}: is {what} of that directory ({MANIFEST}), which "
                              f"'vsj verify' checks: replacing it would break the set; {remedy}")
        if not written_by_vsj(path):
            raise OutputError(f"{shown}: exists and vsj did not write it; vsj never replaces "
                              f"a file it did not write: {remedy}")
    existing = _nearest_existing(path.parent)
    if not existing.is_dir():
        raise OutputError(f"{shown}: cannot create a file there: {existing} is not a directory")
    try:
        fd, named = _temporary_file(existing, path.name)
        os.close(fd)
        if named is not None:
            os.unlink(named)
    except OSError as exc:
        raise OutputError(f"{shown}: cannot write in {existing} ({_reason(exc)})") from None
    _check_space(existing, size, shown)
    return path


@contextlib.contextmanager
def write_errors(option: str, path: str | Path):
    """Turn an `OSError` while writing ``path`` into an `OutputError` that names the option
    (an `atomic_write` that fails leaves the previous file as it was)."""
    try:
        yield
    except OSError as exc:
        raise OutputError(f"{option} {path}: writing failed ({_reason(exc)}); the previous "
                          "file, if any, is unchanged") from None


# --- result sets --------------------------------------------------------------------

def _names_pattern(files: str | Iterable[str]) -> str:
    if isinstance(files, str):
        return files
    return "|".join(re.escape(name) for name in files)


def _exchange(a: Path, b: Path) -> None:
    """Swap the directory entries ``a`` and ``b`` in one step (Linux ``renameat2`` with
    ``RENAME_EXCHANGE``); `OSError` where the system or file system lacks it."""
    try:
        renameat2 = _libc().renameat2
    except (OSError, AttributeError):
        raise OSError(errno.ENOSYS, "renameat2 is not available", str(a)) from None
    if renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b),
                 ctypes.c_uint(_RENAME_EXCHANGE)) != 0:
        code = ctypes.get_errno()
        raise OSError(code, os.strerror(code), str(a), None, str(b))


def _fsync_directory(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _is_mount_point(path: Path) -> bool:
    """Whether ``path`` is a mount point, bind mounts of the same file system included
    (which `os.path.ismount` misses; Linux lists them in /proc/self/mountinfo)."""
    if os.path.ismount(path):
        return True
    with contextlib.suppress(OSError), open("/proc/self/mountinfo", encoding="utf-8") as handle:
        for line in handle:
            fields = line.split()
            point = re.sub(r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)), fields[4])
            if point == str(path):
                return True
    return False


def _lock_holder(fd: int) -> str:
    """'process PID' holding the ``flock`` on the open directory ``fd`` (from /proc/locks),
    or 'another process' where that cannot be told."""
    inode = os.fstat(fd).st_ino
    with contextlib.suppress(OSError), open("/proc/locks", encoding="ascii") as handle:
        for line in handle:
            fields = line.split()
            if len(fields) > 5 and fields[1] == "FLOCK" and \
                    fields[5].rsplit(":", 1)[-1] == str(inode):
                return f"process {fields[4]}"
    return "another process"


def file_record(path: Path) -> dict:
    """``{"sha256": ..., "bytes": ...}`` of a regular file (anything else, such as a FIFO
    that would block the read, raises `OSError` before it is read)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EINVAL, "not a regular file", str(path))
        return _record_of(fd)
    finally:
        os.close(fd)


def _record_of(fd: int) -> dict:
    """`file_record` of the open regular file ``fd``, read from its start (its position
    is left as it was)."""
    digest = hashlib.sha256()
    size = 0
    buffer = bytearray(1 << 20)
    view = memoryview(buffer)
    while count := os.preadv(fd, [buffer], size):
        digest.update(view[:count])
        size += count
    return {"sha256": digest.hexdigest(), "bytes": size}


def read_manifest(directory: Path) -> dict:
    """The manifest of an output directory (``{"sets": {}}`` where there is none or it is
    not vsj's)."""
    try:
        record = json.loads((Path(directory) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"sets": {}}
    sets = record.get("sets") if isinstance(record, dict) else None
    if not isinstance(sets, dict):
        return {"sets": {}}
    return {**record, "sets": {name: entry for name, entry in sets.items()
                               if isinstance(entry, dict) and
                               isinstance(entry.get("files", {}), dict)}}


def clear_staging(staging: str, target: str, disposable: str) -> bool:
    """Remove the staging directory ``staging`` of a result set in ``target``; True when it
    is gone.

    Deletes the files vsj writes (names matching the regular expression ``disposable``)
    and extra links of files that stay elsewhere; anything else, which can only be a file
    put into the directory while vsj was replacing it, is moved into ``target`` (or, where
    that name is taken, left with the staging directory). Self-contained (the watchdog
    runs its source on its own) and safe to run twice at once.
    """
    # lazy: self-contained, the watchdog process runs this function's source alone
    import os
    import re
    import stat

    ours = re.compile(disposable)
    try:
        entries = list(os.scandir(staging))
    except FileNotFoundError:
        return True
    except OSError:
        return False
    kept = 0
    for entry in entries:
        try:
            info = entry.stat(follow_symlinks=False)
            if stat.S_ISREG(info.st_mode) and (ours.fullmatch(entry.name) or info.st_nlink > 1):
                os.unlink(entry.path)
                continue
            destination = os.path.join(target, entry.name)
            if not os.path.lexists(destination):
                os.rename(entry.path, destination)
                continue
        except FileNotFoundError:
            continue
        except OSError:
            pass
        kept += 1
    try:
        os.rmdir(staging)
    except FileNotFoundError:
        pass
    except OSError:
        return False
    return kept == 0


_WATCHDOG = """
import json, os, sys
{clear_staging}
task = json.loads(sys.argv[1])
if sys.stdin.buffer.read() != b"done":  # end of file without 'done': vsj died
    for path in task["clear"]:
        clear_staging(path, task["target"], task["disposable"])
    for path in task["created"]:
        try:
            os.rmdir(path)
        except OSError:
            break
"""


def _source(function) -> str:
    """The source text of a module-level function: its file's lines from its first to
    the last its code covers (what `inspect.getsource` gives, without the tokenizer,
    whose first use takes most of a result set's start)."""
    code = function.__code__
    last = max(end for _, end, _, _ in code.co_positions() if end is not None)
    return "".join(linecache.getlines(code.co_filename)[code.co_firstlineno - 1:last])


def _start_watchdog(lock_fd: int, clear: list[Path], target: Path, created: list[Path]):
    """A process that holds the lock with us and, should we die before telling it 'done',
    removes ``clear`` and the empty directories in ``created`` (deepest first)."""
    task = json.dumps({"clear": [str(p) for p in clear], "target": str(target),
                       "created": [str(p) for p in created], "disposable": _DISPOSABLE})
    code = _WATCHDOG.format(clear_staging=_source(clear_staging))
    try:
        return subprocess.Popen([sys.executable, "-I", "-S", "-c", code, task],
                                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, pass_fds=(lock_fd,),
                                start_new_session=True)
    except (OSError, ValueError):  # none to spare: the next writer clears what we leave
        return None


class ResultSet:
    """The files of one command in an output directory, checked before the work and
    replaced as a unit (see the module docstring)::

        with ResultSet(Path(args.out), "simulate", size=estimate) as results:
            ...                                   # the work
            write_meta(results.path("meta.json"), record)

    ``kind`` names the command (a key of `OUTPUTS`, whose pattern limits the file names
    unless ``files`` gives them: names or a regular expression); ``name`` the set in the
    directory's manifest (default ``kind``); ``option`` the command-line option, for
    messages; ``size`` a conservative estimate of the bytes written. Entering raises
    `OutputError` when the directory is unusable; leaving without an exception commits
    the set, leaving with one discards it and leaves the directory as it was (an
    `OSError` from writing becomes an `OutputError` that says so).
    """

    def __init__(self, path: str | Path, kind: str, *, name: str | None = None,
                 files: str | Iterable[str] | None = None, option: str = "--out",
                 size: int = 0):
        self.out = Path(path)
        self.kind = kind
        self.name = name or kind
        self.option = option
        self.size = int(size)
        self._own = re.compile(_names_pattern(OUTPUTS[kind] if files is None else files))
        self._shown = f"{option} {self.out}"
        self.dir = Path(os.path.realpath(self.out))
        self._token = secrets.token_hex(8)
        self._created: list[Path] = []
        self._locks: list[int] = []
        self._exchange = True
        self._staging: Path | None = None
        self._written: dict[str, None] = {}  # names in the order written
        self._records: dict[str, tuple[tuple, dict]] = {}
        self._sets: dict = {}
        self._old: set[str] = set()
        self._watchdog = None
        self.committed = False

    # entering: the checks, before any work

    def __enter__(self) -> Self:
        self._lock()
        try:
            self._watchdog = _start_watchdog(self._locks[0], self._temporaries(), self.dir,
                                             self._created)
            self._choose_method()
            self._clear_leftovers()
            self._survey()
            _check_space(self.dir, self.size, self._shown)
        except BaseException:
            self._remove_created()
            self._release()
            raise
        return self

    def _make_directory(self) -> None:
        if self.dir.exists() and not self.dir.is_dir():
            raise OutputError(f"{self._shown}: exists and is not a directory")
        missing, path = [], self.dir
        while not path.exists() and path != path.parent:
            missing.append(path)
            path = path.parent
        if not path.is_dir():
            raise OutputError(f"{self._shown}: cannot create the directory: {path} is not a "
                              "directory")
        for directory in reversed(missing):
            try:
                os.mkdir(directory)
            except FileExistsError:
                continue
            except OSError as exc:
                self._remove_created()
                raise OutputError(f"{self._shown}: cannot create the directory "
                                  f"({_reason(exc)})") from None
            self._created.insert(0, directory)

    def _lock(self) -> None:
        for _ in range(100):  # retried while another writer swaps the directory under us
            self._make_directory()
            try:
                fd = os.open(self.dir, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            except FileNotFoundError:
                continue
            except OSError as exc:
                raise OutputError(f"{self._shown}: cannot open the directory "
                                  f"({_reason(exc)})") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _lock_holder(fd)
                os.close(fd)
                self._created = []  # the writer that holds it owns the directory now
                raise OutputError(f"{self._shown}: another vsj command ({holder}) is writing "
                                  "to this directory; wait until it has finished, or choose "
                                  "another directory") from None
            try:
                current = os.stat(self.dir)
            except FileNotFoundError:
                current = None
            opened = os.fstat(fd)
            if current is not None and (current.st_dev, current.st_ino) == \
                    (opened.st_dev, opened.st_ino):
                self._locks.append(fd)
                return
            os.close(fd)  # replaced after we opened it: lock the one there now
        raise OutputError(f"{self._shown}: the directory keeps being replaced")

    def _choose_method(self) -> None:
        """Exchange the directory when the file system can; else replace in place (the
        current directory of this process, a mount point, no ``RENAME_EXCHANGE``)."""
        try:
            cwd = Path.cwd().resolve()
        except OSError:
            cwd = None
        inside = cwd is not None and (cwd == self.dir or self.dir in cwd.parents)
        if not os.access(self.dir, os.W_OK | os.X_OK):  # its owner does not want it changed
            raise OutputError(f"{self._shown}: cannot write in the directory (permission "
                              "denied)")
        self._exchange = not inside and not _is_mount_point(self.dir) and self._can_exchange()
        if not self._exchange:
            try:
                fd, named = _temporary_file(self.dir, PROBE)
                os.close(fd)
                if named is not None:
                    os.unlink(named)
            except OSError as exc:
                raise OutputError(f"{self._shown}: cannot write in the directory "
                                  f"({_reason(exc)})") from None

    def _sibling(self, suffix: str = "") -> Path:
        """The staging directory (the probes of `_can_exchange`: with a suffix)."""
        return self.dir.parent / f".{self.dir.name}.vsj-{self._token}{suffix}"

    def _can_exchange(self) -> bool:
        a, b = self._sibling("p"), self._sibling("q")
        try:
            os.mkdir(a)
        except OSError:  # the parent is not writable: the directory itself may be
            return False
        try:
            os.mkdir(b)
            try:
                _exchange(a, b)
                return True
            except OSError:
                return False
            finally:
                os.rmdir(b)
        except OSError:
            return False
        finally:
            with contextlib.suppress(OSError):
                os.rmdir(a)

    def _temporaries(self) -> list[Path]:
        """Every directory this set may make on its way (for the watchdog to clear)."""
        return [self._sibling(), self._sibling("p"), self._sibling("q"),
                self.dir / f".vsj-{self._token}"]

    def _clear_leftovers(self) -> None:
        """Remove what killed writers of this directory left (we hold its lock)."""
        sibling = re.compile(rf"\.{re.escape(self.dir.name)}\.vsj-[0-9a-f]{{16}}[pq]?")
        with contextlib.suppress(OSError):
            for entry in os.scandir(self.dir.parent):
                if sibling.fullmatch(entry.name) and entry.is_dir(follow_symlinks=False):
                    clear_staging(entry.path, str(self.dir), _DISPOSABLE)
        for entry in os.scandir(self.dir):
            if _IN_PLACE_STAGING.fullmatch(entry.name) and entry.is_dir(follow_symlinks=False):
                clear_staging(entry.path, str(self.dir), _DISPOSABLE)
            elif _TEMPORARY.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(entry.path)

    def _survey(self) -> None:
        """Sort the directory's files into this set's (replaced), other sets' (kept), and
        files vsj did not write (refused)."""
        self._sets = read_manifest(self.dir)["sets"]
        mine = self._sets.get(self.name, {}).get("files", {})
        others = {f for name, entry in self._sets.items() if name != self.name
                  for f in entry.get("files", {})}
        foreign = []
        for entry in os.scandir(self.dir):
            name = entry.name
            if name == MANIFEST:
                continue
            if not entry.is_file(follow_symlinks=False):
                foreign.append(name + ("/" if entry.is_dir(follow_symlinks=False) else ""))
            elif name in mine:
                self._old.add(name)
            elif name not in others:  # not in the manifest, whatever its name
                foreign.append(name)
        if foreign:
            foreign.sort()
            listed = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more"
                                               if len(foreign) > 5 else "")
            raise OutputError(f"{self._shown}: holds files that vsj did not write ({listed}: "
                              f"not recorded in a {MANIFEST}); vsj replaces the results in a "
                              "directory as a whole and never removes other files: move them "
                              "away or choose another directory")

    # the work writes through `path`

    def _ensure_staging(self) -> Path:
        if self._staging is not None:
            return self._staging
        if self._exchange:
            staging = self._sibling()
            os.mkdir(staging)
            self._staging = staging
            fd = os.open(staging, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
            self._locks.append(fd)
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # it becomes the directory
        else:
            staging = self.dir / f".vsj-{self._token}"
            os.mkdir(staging, 0o700)
            self._staging = staging
        return staging

    def path(self, name: str) -> Path:
        """Where to write the set's file ``name`` (in the staging directory; it appears
        under ``out / name`` when the set is committed)."""
        if "/" in name or not self._own.fullmatch(name):
            raise ValueError(f"{name!r} is not a file of a {self.kind!r} result set")
        if not self._locks:
            raise RuntimeError("a ResultSet is written inside its 'with' block")
        self._written[name] = None
        return self._ensure_staging() / name

    @contextlib.contextmanager
    def write(self, name: str, mode: str = "wb"):
        """`atomic_write` of the set's file ``name`` (`path`), hashed for the manifest
        while its data is synced to disk (`hashes` then has its record at once)."""
        path = self.path(name)

        def record(fd: int) -> None:
            info = os.fstat(fd)
            self._records[name] = ((info.st_ino, info.st_size, info.st_mtime_ns),
                                   _record_of(fd))

        with atomic_write(path, mode, when_complete=record) as handle:
            yield handle

    @property
    def written(self) -> list[str]:
        """Names of the set's files, in the order they were asked for."""
        return list(self._written)

    def hashes(self) -> dict[str, dict]:
        """``{name: {"sha256", "bytes"}}`` of the files written so far."""
        out = {}
        if self._staging is None:
            return out
        for name in sorted(self._written):
            path = self._staging / name
            if not path.exists():
                continue
            info = os.stat(path)
            key = (info.st_ino, info.st_size, info.st_mtime_ns)
            if name not in self._records or self._records[name][0] != key:
                self._records[name] = (key, file_record(path))
            out[name] = self._records[name][1]
        return out

    # leaving: commit, or discard

    def __exit__(self, kind, exc, traceback) -> bool:
        try:
            if kind is None:
                try:
                    self._commit()
                except BaseException as error:
                    self._discard()
                    if isinstance(error, OSError):
                        raise self._write_error(error) from None
                    raise
            else:
                self._discard()
                if isinstance(exc, OSError) and self.from_writing(exc):
                    raise self._write_error(exc) from None
        finally:
            self._release()
        return False

    def from_writing(self, exc: OSError) -> bool:
        """Whether ``exc`` comes from writing the set (and so discards it)."""
        if self._staging is None:
            return False
        name = exc.filename if isinstance(exc.filename, str) else None
        return name is None or name.startswith((str(self._staging), str(self.dir)))

    def _write_error(self, exc: OSError) -> OutputError:
        what = Path(exc.filename).name if isinstance(exc.filename, str) else "the results"
        if not self._exchange and self.committed is None:
            state = "the directory now holds a mixed set, which 'vsj verify' reports"
        else:
            state = "the directory is unchanged"
        return OutputError(f"{self._shown}: writing {what} failed ({_reason(exc)}); {state}")

    def _manifest(self, written: dict, complete: bool) -> dict:
        sets = {}
        for name, entry in self._sets.items():
            if name == self.name or not isinstance(entry, dict):
                continue
            files = {f: r for f, r in entry.get("files", {}).items() if f not in written}
            if files:
                sets[name] = {**entry, "files": files}
        sets[self.name] = {"kind": self.kind, "vsj_version": __version__,
                           "complete": complete, "files": written}
        return {"about": "vsj result sets in this directory, each with the SHA-256 of its "
                         "files; 'vsj verify DIR' checks them",
                "sets": dict(sorted(sets.items()))}

    def _write_manifest(self, directory: Path, written: dict, complete: bool) -> None:
        with atomic_write(directory / MANIFEST) as handle:
            handle.write(json.dumps(self._manifest(written, complete), indent=1) + "\n")

    def _commit(self) -> None:
        staging = self._ensure_staging()
        written = self.hashes()
        if self._exchange:
            self._carry_others(staging, written)
            self._write_manifest(staging, written, complete=True)
            for name in written:
                _fsync_file(staging / name)
            info = os.stat(self.dir)  # the directory keeps its permissions and owner
            os.chmod(staging, stat.S_IMODE(info.st_mode))
            if (info.st_uid, info.st_gid) != (os.getuid(), os.getgid()):
                with contextlib.suppress(OSError):
                    os.chown(staging, info.st_uid, info.st_gid)
            _fsync_directory(staging)
            _exchange(staging, self.dir)
            self.committed = True
            with contextlib.suppress(OSError):
                _fsync_directory(self.dir.parent)
            # the old set: its own files and manifest go, and the other sets' links; a file
            # put into the directory since `_carry_others` is moved back, whatever its name
            clear_staging(str(staging), str(self.dir), self._old_files())
            return
        self._write_manifest(self.dir, written, complete=False)
        self.committed = None  # from here on the directory holds a mixed set
        for name in written:
            os.replace(staging / name, self.dir / name)
        for name in self._old.difference(written):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.dir / name)
        self._write_manifest(self.dir, written, complete=True)
        self.committed = True
        with contextlib.suppress(OSError):
            _fsync_directory(self.dir)
            os.rmdir(staging)

    def _old_files(self) -> str:
        """The names (a regular expression) of what the directory held of this set before
        the commit: its files and the manifest, and `atomic_write`'s temporaries of them."""
        names = _names_pattern(sorted(self._old) + [MANIFEST])
        return rf"{names}|\.(?:{names})\.vsj-tmp-\w+"

    def _carry_others(self, staging: Path, written: dict) -> None:
        """Hard-link the other sets' files into the staging directory (copies where the
        file system has no hard links)."""
        for entry in os.scandir(self.dir):
            name = entry.name
            if name == MANIFEST or name in written or name in self._old or \
                    _TEMPORARY.fullmatch(name):
                continue
            if not entry.is_file(follow_symlinks=False):
                raise OutputError(f"{self._shown}: {name} appeared in the directory while vsj "
                                  "was writing; the directory is unchanged")
            try:
                os.link(entry.path, staging / name, follow_symlinks=False)
            except OSError as exc:
                if exc.errno not in (errno.EPERM, errno.EMLINK, errno.EOPNOTSUPP, errno.EXDEV):
                    raise
                shutil.copy2(entry.path, staging / name)

    def _discard(self) -> None:
        if self._staging is not None and self.committed is not True:
            if self._exchange:
                clear_staging(str(self._staging), str(self.dir), _DISPOSABLE)
            else:
                shutil.rmtree(self._staging, ignore_errors=True)
        self._remove_created()

    def _remove_created(self) -> None:
        for directory in self._created:
            try:
                os.rmdir(directory)
            except OSError:
                break
        self._created = []

    def _release(self) -> None:
        if self._watchdog is not None:
            with contextlib.suppress(OSError):
                self._watchdog.stdin.write(b"done")
                self._watchdog.stdin.close()
            self._watchdog.wait()
            self._watchdog = None
        for fd in self._locks:
            os.close(fd)  # and with it the lock
        self._locks = []


def verify(directory: str | Path) -> list[str]:
    """What is wrong with the result sets in ``directory`` (empty when every set in its
    manifest is complete, every file has the size and SHA-256 recorded, in the manifest
    and in ``meta.json``'s ``files``, and the directory holds no other file). Only
    regular files are read: a FIFO or a device is named, never opened for reading."""
    directory = Path(directory)
    if not regular_file(directory / MANIFEST):
        return [f"{directory}: no {MANIFEST}"]
    sets = read_manifest(directory)["sets"]
    if not sets:
        return [f"{directory / MANIFEST}: not a vsj manifest"]
    problems = []
    listed = {MANIFEST}
    for name, entry in sets.items():
        if not entry.get("complete"):
            problems.append(f"set {name!r}: incomplete (its writing was interrupted)")
        files = dict(entry.get("files", {}))
        listed |= set(files)
        if "meta.json" in files and regular_file(directory / "meta.json"):
            with contextlib.suppress(InputError, ValueError, AttributeError):
                meta = json.loads(read_bytes(directory / "meta.json", "meta.json",
                                             SMALL_OUTPUT_BYTES))
                for f, record in meta.get("files", {}).items():
                    if f not in files:
                        problems.append(f"set {name!r}: {f}: meta.json records it, "
                                        f"{MANIFEST} does not")
                    elif files[f] != record:
                        problems.append(f"set {name!r}: {f}: meta.json and {MANIFEST} differ")
        problems += recorded_file_problems(directory, files, f"set {name!r}: ")
    for entry in sorted(os.listdir(directory)):
        if entry not in listed:
            kind = ("left by an interrupted write (the next vsj command writing here "
                    "removes it)" if _TEMPORARY.fullmatch(entry) or
                    _IN_PLACE_STAGING.fullmatch(entry) else
                    f"a foreign file (not recorded in {MANIFEST})")
            problems.append(f"{entry}: {kind}")
    return problems


def recorded_file_problems(directory: Path, files: Mapping[str, dict],
                           prefix: str = "") -> list[str]:
    """What is wrong with each file a manifest records (``files``: name -> its
    `file_record`) in ``directory``: missing, not a regular file, or changed; each
    message begins with ``prefix``."""
    problems = []
    for name, record in sorted(files.items()):
        path = directory / name
        if not os.path.lexists(path):
            problems.append(f"{prefix}{name} is missing")
        elif not regular_file(path):
            problems.append(f"{prefix}{name} is not a regular file")
        elif file_record(path) != record:
            problems.append(f"{prefix}{name} has changed (its SHA-256 differs)")
    return problems


def regular_file(path: Path) -> bool:
    """Whether ``path`` is a regular file (not following a symbolic link)."""
    try:
        return stat.S_ISREG(os.stat(path, follow_symlinks=False).st_mode)
    except OSError:
        return False


# --- size estimates -----------------------------------------------------------------


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else str(v)
    if isinstance(value, (np.integer,)):
        return int(value)
    return value


def write_meta(path: Path, record: dict) -> None:
    """Write ``record`` as the JSON metadata of a result (atomically), vsj's version
    first; NumPy values become plain JSON."""
    record = {"vsj_version": __version__, **record}
    text = json.dumps(_jsonable(record), indent=2, sort_keys=False)
    with atomic_write(path) as handle:
        handle.write(text + "\n")
