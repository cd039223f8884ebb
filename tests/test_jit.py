"""The guard against stale compiled code (`vsj.jit.drop_stale_cache`)."""

import os

from vsj.jit import drop_stale_cache


def _package(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub" / "__pycache__").mkdir(parents=True)
    (package / "a.py").write_text("x = 1\n")
    (package / "sub" / "b.py").write_text("y = 2\n")
    return package


def test_cached_functions_go_when_any_source_changes(tmp_path):
    package = _package(tmp_path)
    stamp = package / "__pycache__" / "stamp"
    cached = package / "sub" / "__pycache__" / "b.f-1.py311.nbi"
    cached.write_text("index")
    assert drop_stale_cache(package, stamp)  # no stamp yet: the cache cannot be trusted
    assert not cached.exists()

    cached.write_text("index")  # compiled again from the current sources
    assert not drop_stale_cache(package, stamp)
    assert cached.exists()

    # an edit of another file (a.py) invalidates b's cached functions too: they
    # may have inlined code from a.py
    a = package / "a.py"
    later = a.stat().st_mtime_ns + 10 ** 9
    os.utime(a, ns=(later, later))
    assert drop_stale_cache(package, stamp)
    assert not cached.exists()


def test_a_new_source_file_counts_as_a_change(tmp_path):
    package = _package(tmp_path)
    stamp = package / "__pycache__" / "stamp"
    drop_stale_cache(package, stamp)
    cached = package / "sub" / "__pycache__" / "b.f-1.py311.nbc"
    cached.write_text("code")
    (package / "c.py").write_text("z = 3\n")
    assert drop_stale_cache(package, stamp)
    assert not cached.exists()
    pyc = package / "sub" / "__pycache__" / "b.cpython-311.pyc"  # Python's own cache stays
    pyc.write_text("bytecode")
    (package / "c.py").write_text("z = 40\n")  # a new size: timestamps may be coarse
    assert drop_stale_cache(package, stamp)
    assert pyc.exists()
