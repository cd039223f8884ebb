"""A result set's large file is hashed while it is synced to disk (`ResultSet.write`): the
record is that of the file as committed, and a failing sync still fails the set."""

import errno
import hashlib
import os

import pytest

from vsj.output import OutputError, ResultSet, read_manifest, verify
from vsj.output import files


def payload() -> bytes:
    """A few reads' worth of bytes, not a whole number of them."""
    return os.urandom(3 * 2 ** 20 + 12345)


def test_a_file_written_through_its_set_is_recorded_as_committed(tmp_path, monkeypatch):
    data = payload()
    reread = []
    monkeypatch.setattr(files, "file_record",
                        lambda path: reread.append(path) or pytest.fail("read again"))
    out = tmp_path / "out"
    with ResultSet(out, "simulate") as results:
        with results.write("trajectory.nc", "w+b") as handle:
            handle.write(data[:-1000])
            handle.write(data[-1000:])  # still in the handle's buffer when the block ends
        recorded = results.hashes()["trajectory.nc"]
    assert recorded == {"sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}
    assert read_manifest(out)["sets"]["simulate"]["files"]["trajectory.nc"] == recorded
    assert (out / "trajectory.nc").read_bytes() == data and reread == []
    monkeypatch.undo()
    assert verify(out) == []


def test_a_failing_sync_fails_the_set(tmp_path, monkeypatch):
    out = tmp_path / "out"
    with ResultSet(out, "simulate") as results:
        with results.write("meta.json", "w") as handle:
            handle.write("{}\n")
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken(fd):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(files.os, "fsync", broken)
    with pytest.raises(OutputError, match="writing trajectory.nc failed"):
        with ResultSet(out, "simulate") as results:
            with results.write("trajectory.nc", "w+b") as handle:
                handle.write(payload())
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
