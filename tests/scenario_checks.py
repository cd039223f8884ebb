"""What the scenario tests of the controller and the environment share: writing a
scenario file and checking that ``vsj simulate`` refuses it as a user should see it."""

from __future__ import annotations

from pathlib import Path

from vsj.cli import main


def write(tmp_path: Path, text: str, name: str = "scenario.toml") -> Path:
    """``text`` as the file ``name`` in ``tmp_path``."""
    path = tmp_path / name
    path.write_text(text)
    return path


def fails(tmp_path, capsys, text: str, *expected: str) -> str:
    """`vsj simulate` refuses ``text``: exit code 2, no traceback, nothing written, the
    file's name and every expected text in the message. Returns the message."""
    out = tmp_path / "out"
    path = write(tmp_path, text)
    code = main(["simulate", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"vsj: error: {path}: ") and "Traceback" not in err, err
    for text in expected:
        assert text in err, (text, err)
    assert not out.exists()
    return err
