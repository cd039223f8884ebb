"""``extends`` and the reading of user files, against what issue 31 (item 10) found: a
symlink loop, a chain of 2000 files, /dev/zero and a FIFO as a parent, errors in a
parent blamed on the child, a missing parent that does not name the file naming it.

A case that could hang or exhaust memory if the fix regressed (a FIFO, a device) runs
in a child process with a timeout and a cap on its address space, so that it fails
instead of stopping the suite.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from vsj import measurements, params, scenario
from vsj.errors import TEXT_BYTES, InputError, read_text

#: A change to the bundled set that every test can look for.
STICTION = 'stiction = { value = "40 mN m", source = "test" }\n'
#: A child process needs a few seconds to import vsj; a minute means it hangs.
TIMEOUT = 60.0
#: Address space of a child process [bytes]: vsj and NumPy need a few hundred MB, so a
#: read of /dev/zero that regressed stops at a MemoryError instead of filling the machine.
ADDRESS_SPACE = 3 << 30


def _child(code: str, *args: str) -> subprocess.CompletedProcess:
    """``python -c code args`` with `TIMEOUT` and `ADDRESS_SPACE`; TimeoutExpired if it hangs."""
    def limit():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True,
                          text=True, timeout=TIMEOUT, preexec_fn=limit, env=env)


LOAD = """
import sys
from vsj import params
from vsj.errors import InputError
try:
    params.load(sys.argv[1])
except InputError as exc:
    print(exc)
    sys.exit(2)
"""


def _child_load(path: Path) -> str:
    """The `InputError` that loading ``path`` raises, from a child process."""
    done = _child(LOAD, str(path))
    assert done.returncode == 2, done.stderr
    return done.stdout


def _child_file(tmp_path: Path, parent: str) -> Path:
    child = tmp_path / "child.toml"
    child.write_text(f'extends = "{parent}"\n[transmission]\n{STICTION}')
    return child


# ------------------------------------------------------------- files that are no files

def test_a_fifo_as_a_parent_is_refused_without_waiting(tmp_path):
    os.mkfifo(tmp_path / "parent.toml")
    child = _child_file(tmp_path, "parent.toml")
    message = _child_load(child)
    assert message.startswith(f"{child}: extends = 'parent.toml': ")
    assert f"{tmp_path / 'parent.toml'}: cannot read parameter file: a FIFO" in message


def test_dev_zero_as_a_parent_is_refused_without_reading(tmp_path):
    child = _child_file(tmp_path, "/dev/zero")
    message = _child_load(child)
    assert message.startswith(f"{child}: extends = '/dev/zero': /dev/zero: cannot read "
                              "parameter file: a character device, not a regular file")


def test_a_symlink_loop_as_a_parent_is_an_input_error(tmp_path):
    (tmp_path / "a.toml").symlink_to(tmp_path / "b.toml")
    (tmp_path / "b.toml").symlink_to(tmp_path / "a.toml")
    child = _child_file(tmp_path, "a.toml")
    with pytest.raises(InputError) as caught:
        params.load(child)
    message = str(caught.value)
    assert message.startswith(f"{child}: extends = 'a.toml': {tmp_path / 'a.toml'}: cannot "
                              "read parameter file")
    assert "symbolic links" in message  # the system's reason, ELOOP


def test_a_directory_as_a_parent_is_refused(tmp_path):
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(InputError, match=r"child.toml: extends = 'dir.toml': .*a directory, "
                                         r"not a regular file"):
        params.load(_child_file(tmp_path, "dir.toml"))


def test_a_parent_larger_than_a_parameter_file_can_be_is_refused_up_front(tmp_path):
    """A valid parameter file padded past `MAX_BYTES` with comments is refused by its
    size; padded to exactly `MAX_BYTES`, it loads."""
    text = f'extends = "second_prototype"\n[transmission]\n{STICTION}'
    padding = params.MAX_BYTES - len(text.encode())
    line = "#" * 99 + "\n"
    exact = text + line * (padding // len(line)) + "#" * (padding % len(line))
    parent = tmp_path / "parent.toml"
    parent.write_text(exact)
    assert parent.stat().st_size == params.MAX_BYTES
    loaded = params.load(_child_file(tmp_path, "parent.toml"))
    assert loaded["transmission.stiction"] == 0.04
    parent.write_text(exact + "#")
    with pytest.raises(InputError) as caught:
        params.load(tmp_path / "child.toml")
    assert str(caught.value) == (
        f"{tmp_path / 'child.toml'}: extends = 'parent.toml': {parent}: cannot read "
        f"parameter file: 1.0 MiB; a parameter file holds at most 1.0 MiB "
        f"({params.MAX_BYTES} bytes)")


def test_a_parameter_file_itself_that_is_a_device_is_refused():
    with pytest.raises(InputError, match="^/dev/null: cannot read parameter file: a "
                                         "character device, not a regular file$"):
        params.load("/dev/null")


# ------------------------------------------------------------------ chains and loops

def _chain(folder: Path, count: int) -> Path:
    """``count`` files in ``folder``, each extending the next; the last extends the
    bundled set and sets the stiction; the first file's path."""
    folder.mkdir(exist_ok=True)
    for k in range(count - 1):
        (folder / f"p{k}.toml").write_text(f'extends = "p{k + 1}.toml"\n')
    (folder / f"p{count - 1}.toml").write_text(
        f'extends = "second_prototype"\n[transmission]\n{STICTION}')
    return folder / "p0.toml"


def test_a_chain_of_2000_files_is_refused_with_a_clear_message(tmp_path):
    first = _chain(tmp_path, 2000)
    last = params.MAX_EXTENDS - 1
    with pytest.raises(InputError) as caught:
        params.load(first)
    assert str(caught.value) == (
        f"{tmp_path / f'p{last}.toml'}: extends = 'p{last + 1}.toml': a chain of more than "
        f"{params.MAX_EXTENDS} parameter files ({first} -> ... -> {tmp_path / f'p{last}.toml'}"
        f" -> {tmp_path / f'p{last + 1}.toml'}); at most {params.MAX_EXTENDS} are followed")


def test_a_chain_of_the_longest_length_allowed_loads(tmp_path):
    """`MAX_EXTENDS` files in all (the bundled set the last of them) load; one more does
    not: the bound is neither one short nor one long."""
    assert params.load(_chain(tmp_path / "a", params.MAX_EXTENDS - 1))[
        "transmission.stiction"] == 0.04
    with pytest.raises(InputError, match="a chain of more than"):
        params.load(_chain(tmp_path / "b", params.MAX_EXTENDS))


def test_a_cycle_through_a_symlink_names_the_files(tmp_path):
    (tmp_path / "a.toml").write_text('extends = "b.toml"\n')
    (tmp_path / "b.toml").write_text('extends = "alias.toml"\n')
    (tmp_path / "alias.toml").symlink_to(tmp_path / "a.toml")
    with pytest.raises(InputError) as caught:
        params.load(tmp_path / "a.toml")
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    assert str(caught.value) == (f"{b}: extends = 'alias.toml' makes a cycle of parameter "
                                 f"files: {a} -> {b} -> {a}")


# ------------------------------------------------------ the file that holds the problem

def test_a_missing_parent_names_the_file_that_names_it(tmp_path):
    child = _child_file(tmp_path, "missing.toml")
    with pytest.raises(InputError) as caught:
        params.load(child)
    assert str(caught.value) == (f"{child}: extends = 'missing.toml': "
                                 f"{tmp_path / 'missing.toml'}: cannot read parameter file "
                                 "(No such file or directory)")


def test_errors_in_a_parent_name_the_parent(tmp_path):
    parent = tmp_path / "parent.toml"
    parent.write_text('extends = "second_prototype"\n[transmission]\n'
                      'stiction = { value = "-4 mN m", source = "typo" }\n'
                      '[differential]\nstiktion = { value = "1 mN m", source = "x" }\n')
    child = tmp_path / "child.toml"
    child.write_text('extends = "parent.toml"\n[differential]\n'
                     'inertia_x = { value = "-1 kg m^2", source = "typo" }\n')
    with pytest.raises(InputError) as caught:
        params.load(child)
    lines = str(caught.value).splitlines()
    assert f"{parent}: transmission.stiction = '-4 mN m': must be >= 0 N m " \
           "(transmission stiction parameter, k_T (carrier side))" in lines
    assert any(line.startswith(f"{parent}: differential.stiktion: unknown key") for line in lines)
    assert any(line.startswith(f"{child}: differential.inertia_x = '-1 kg m^2': must be >= 0")
               for line in lines)
    assert len(lines) == 3


def test_a_value_a_child_overrides_is_blamed_on_the_child(tmp_path):
    """The parent's bad stiction is replaced by the child's, so nothing is wrong; the
    child's own bad value is the child's."""
    parent = tmp_path / "parent.toml"
    parent.write_text('extends = "second_prototype"\n[transmission]\n'
                      'stiction = { value = "-4 mN m", source = "typo" }\n')
    child = _child_file(tmp_path, "parent.toml")
    assert params.load(child)["transmission.stiction"] == 0.04
    child.write_text('extends = "parent.toml"\n[transmission]\n'
                     'stiction = { value = "4 kg", source = "typo" }\n')
    with pytest.raises(InputError, match=rf"^{child}: transmission.stiction: '4 kg' has unit "):
        params.load(child)


def test_a_relation_between_keys_of_two_files_names_both(tmp_path):
    parent = tmp_path / "parent.toml"
    parent.write_text('extends = "second_prototype"\n[pivot]\n'
                      'q_max = { value = "-2.5 cm", source = "typo" }\n')
    child = tmp_path / "child.toml"
    child.write_text('extends = "parent.toml"\n[pivot]\n'
                     'q_min = { value = "-2 cm", source = "bench" }\n')
    with pytest.raises(InputError, match=rf"^{parent} and {child}: pivot.q_min must be below "
                                         r"pivot.q_max \(pivot.q_max = -2.5 cm, pivot.q_min = "
                                         r"-2 cm\)$"):
        params.load(child)


def test_bad_toml_in_a_parent_names_the_parent(tmp_path):
    (tmp_path / "parent.toml").write_text("[transmission\n")
    with pytest.raises(InputError, match=rf"^{tmp_path / 'parent.toml'}: not valid TOML"):
        params.load(_child_file(tmp_path, "parent.toml"))


# ------------------------------------------------------- the other readers of user files

def test_read_text_reads_a_file_of_exactly_its_limit_and_no_more(tmp_path):
    path = tmp_path / "f.txt"
    path.write_bytes(b"x" * 100)
    assert read_text(path, "test file", limit=100) == "x" * 100
    with pytest.raises(InputError, match="f.txt: cannot read test file: 101 bytes; a test "
                                         r"file holds at most 100 bytes \(100 bytes\)$"):
        path.write_bytes(b"x" * 101)
        read_text(path, "test file", limit=100)
    # /proc files report no size: what is read is counted
    with pytest.raises(InputError, match=r"/proc/self/maps: .*more than 10 bytes"):
        read_text("/proc/self/maps", "test file", limit=10)


def test_a_scenario_that_is_a_fifo_is_refused_by_the_command(tmp_path):
    fifo = tmp_path / "scenario.toml"
    os.mkfifo(fifo)
    done = _child("import sys\nfrom vsj.cli import main\nsys.exit(main(sys.argv[1:]))",
                  "simulate", str(fifo), "--out", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr
    assert done.stderr == (f"vsj: error: {fifo}: cannot read scenario file: a FIFO (named "
                           "pipe), not a regular file\n")
    assert not (tmp_path / "out").exists()


def test_a_measurement_file_that_is_a_device_is_refused():
    done = _child("import sys\nfrom vsj import measurements\n"
                  "from vsj.errors import InputError\n"
                  "try:\n    measurements.read('/dev/zero')\n"
                  "except InputError as exc:\n    print(exc)\n    sys.exit(2)\n")
    assert done.returncode == 2, done.stderr
    assert done.stdout == ("/dev/zero: cannot read measurement file: a character device, "
                           "not a regular file\n")


def test_a_linear_model_file_that_is_a_fifo_is_refused(tmp_path):
    fifo = tmp_path / "model.json"
    os.mkfifo(fifo)
    done = _child("import sys\nfrom vsj import linear\nfrom vsj.errors import InputError\n"
                  "try:\n    linear.load(sys.argv[1])\n"
                  "except InputError as exc:\n    print(exc)\n    sys.exit(2)\n", str(fifo))
    assert done.returncode == 2, done.stderr
    assert done.stdout == (f"{fifo}: cannot read linear model file: a FIFO (named pipe), not "
                           "a regular file\n")


def test_each_kind_of_file_has_its_limit(tmp_path):
    """A scenario may hold far more than a parameter file (a table input), a signal log
    far more than a scenario."""
    assert params.MAX_BYTES < TEXT_BYTES < measurements.MAX_BYTES
    big = tmp_path / "big.toml"
    with open(big, "wb") as handle:
        handle.truncate(TEXT_BYTES + 1)  # sparse: nothing is written, nothing must be read
    with pytest.raises(InputError, match="big.toml: cannot read scenario file: 64.0 MiB; a "
                                         "scenario file holds at most 64.0 MiB"):
        scenario.load(str(big))
    cov = tmp_path / "fit.json"
    with open(cov, "wb") as handle:
        handle.truncate(TEXT_BYTES + 1)
    from vsj.sweep.spec import read_covariance

    with pytest.raises(InputError, match="fit.json: cannot read covariance file: 64.0 MiB"):
        read_covariance(cov, "sweep.toml")
