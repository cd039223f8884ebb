"""How vsj compiles its numerical kernels (one place for the numba flags).

``kernel`` compiles a function once and caches it on disk; ``inline`` does the
same for small helpers that are inlined into their callers.

``error_model="numpy"`` makes a division by zero give inf or NaN instead of
raising: the engine checks for non-finite states and reports them with time
and state, and the raising paths (with the reference counting they drag into
every hot loop) cost up to a microsecond per evaluation.

numba checks a cached function against its own source file only, not against
the functions it calls from other files: after an edit of, say, the
time-stepper, the batch kernel would load its old compiled copy of it. On
import, `drop_stale_cache` therefore compares the package's sources with those
the cache was made from and removes every cached function when any differs.
"""

import hashlib
import os
from pathlib import Path

from numba import njit

_PACKAGE = Path(__file__).parent
_STAMP = _PACKAGE / "__pycache__" / "numba-sources.sha1"


def _sources_digest(package: Path) -> str:
    """Digest of the names, sizes and modification times of the package's sources
    (what numba itself compares, file by file)."""
    digest = hashlib.sha1()
    for path in sorted(package.rglob("*.py")):
        stat = path.stat()
        digest.update(f"{path.relative_to(package)}:{stat.st_size}:{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()


def drop_stale_cache(package: Path = _PACKAGE, stamp: Path = _STAMP) -> bool:
    """Remove the package's cached compiled functions if its sources changed since
    they were cached; returns True if it removed them.

    Only the default cache (``__pycache__`` beside the sources) is handled; a
    read-only installation is left alone (numba then caches elsewhere, and an
    installation replaces every file, which numba does notice).
    """
    current = _sources_digest(package)
    try:
        if stamp.read_text() == current:
            return False
    except OSError:
        pass
    try:
        for cached in package.rglob("__pycache__/*.nb[ic]"):
            cached.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        partial = stamp.with_suffix(f".{os.getpid()}")
        partial.write_text(current)
        partial.replace(stamp)
    except OSError:
        return False
    return True


drop_stale_cache()

kernel = njit(cache=True, error_model="numpy")
inline = njit(cache=True, error_model="numpy", inline="always")
parallel = njit(cache=True, error_model="numpy", parallel=True)
#: For allocation-free inner loops that receive every array from their caller
#: (the time-stepper's loop): compiled without reference counting, which in a
#: branchy loop over many arrays costs a call and an atomic add per array use.
loop = njit(cache=True, error_model="numpy", _nrt=False)
