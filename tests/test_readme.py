"""The README says what the code does: its commands, flags, snippets, names, files and
figures are checked against the code, whatever README.md holds (the checks are in
tests/readme_checks.py; no list of the README's commands is kept).

* **Commands** (``vsj ...`` and ``make ...`` lines of code blocks, fenced or indented,
  in document order). Every subcommand and flag must exist in the real parser
  (`vsj.cli.build_parser`, names spelt in full) and every value must parse (choices and
  types); a complete command is then parsed whole. A synopsis (``[--flag VALUE]``,
  ``FILE``-style placeholders) is checked flag by flag, as are ``vsj ...`` spans in the
  prose. ``make`` targets must exist in the Makefile.
* A complete command is **run** (in process through `vsj.cli.main`, expecting exit code
  0), in one temporary directory shared by the whole README, so that it reads what the
  README's earlier commands wrote; a relative input path that only the repository holds
  (``examples/...``) is given from the repository. It is only **parsed** when an input
  file exists nowhere (a reader's own ``my_params.toml``), or when its subcommand is in
  `readme_checks.COSTLY` (datasheet, fmu, fit wrist, sweep; reproduce unless it shows
  ``--reduced --only``): each takes many seconds or a C compiler run, and a test file of
  its own runs it. For the README of this commit that runs the Quick start, the
  Characterisation chain (synth, fit friction, planetary and stiffness, then simulate
  with the fitted set), linearize, synth wrist, excite and msl, each a few seconds at
  most. Which command ran and which was only parsed is printed (``pytest -s``).
* **Flags in the prose** (```--flag value``` spans) must belong to a command that the
  same ``##`` section names (to any command where it names none), with a valid value.
* **Python** code blocks are executed in that directory, after the commands above them.
* **TOML** code blocks are loaded by the loader of the file they show
  (`doc_examples.check_toml`: sweep file with its names checked, experiment, scenario,
  parameter file).
* **Names**: ``vsj.module.attr`` spans, and ``Class.attr`` / ``Class(..., keyword=...)``
  spans of a class that vsj defines, resolve; ``vsj_*`` C names are in the C sources;
  paths into the repository (``src/...``, ``tests/...``; ``vsj/...`` and
  ``engine/c/...`` inside ``src/``) and bare source file names (``planetary.py``) exist.
* **Figures**: each image the README shows exists, and ``make figures`` (the target that
  regenerates them by running the README's own snippet, tools/readme_figure.py) writes
  it, so that none is made by hand.
* **Length**: at most 200 lines; the manual is the documentation site (docs/, whose
  pages tests/test_docs.py checks the same way).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from readme_checks import (code_block_problems, figure_problems, name_problems,
                           prose_problems)

README = Path(__file__).resolve().parents[1] / "README.md"
sys.path.insert(0, str(README.parent / "tools"))  # readme_figure


#: The README gets a reader running and points to the site (issue 35).
MAX_LINES = 200


def test_readme_is_short_and_points_to_the_site():
    text = README.read_text()
    assert len(text.splitlines()) <= MAX_LINES, f"README.md has {len(text.splitlines())} lines"
    assert "make docs" in text
    # each row of its capability table links to a page of the user guide that exists
    links = re.findall(r"\]\((docs/[^)#]+\.md)\)", text)
    assert len(links) >= 10
    missing = [link for link in links if not (README.parent / link).is_file()]
    assert not missing, f"README.md links to pages that do not exist: {missing}"


def test_the_readme_figure_is_what_its_snippet_draws(tmp_path, monkeypatch):
    """The snippet saves the figure the README shows, under the name `make figures`
    copies, so the figure cannot be from another run than the snippet's."""
    import readme_figure
    monkeypatch.chdir(tmp_path)  # the tool moves into its directory; this moves back
    monkeypatch.setenv("MPLBACKEND", "Agg")
    assert readme_figure.main([str(tmp_path / "run")]) == 0
    text = README.read_text()
    shown = re.findall(r"!\[[^\]]*\]\(docs/([^)]+)\)", text)
    saved = re.findall(r"savefig\(\"([^\"]+)\"", text)
    # the snippet's figure is shown, and the tool wrote it (the other figure the README
    # shows is the explorer's screenshot, which make figures takes from its own tool)
    assert saved and set(saved) <= set(shown), (saved, shown)
    assert all((tmp_path / "run" / name).is_file() for name in saved), saved


def test_readme_code_blocks_run(tmp_path, monkeypatch):
    """Every command of the README's code blocks exists and parses, the cheap ones run,
    and its Python and TOML blocks run and load, in document order in one directory."""
    monkeypatch.chdir(tmp_path)
    problems, log = code_block_problems(README.read_text(), tmp_path)
    print("\n".join(log))
    assert not problems, "\n".join(problems)
    assert any(": ran: " in line for line in log), "no command of the README was run"


def test_readme_prose_names_real_commands_and_flags():
    problems = prose_problems(README.read_text())
    assert not problems, "\n".join(problems)


def test_readme_names_files_and_modules_that_exist():
    problems = name_problems(README.read_text())
    assert not problems, "\n".join(problems)


def test_readme_figures_exist_and_make_figures_writes_them():
    text = README.read_text()
    assert "![" in text, "the README shows no figure: nothing to check"
    problems = figure_problems(text)
    assert not problems, "\n".join(problems)


#: A document with one mistake of each kind the checks are for, beside correct lines.
FLAWED = """# A document

## Commands

```
vsj scenarios                            # correct: runs
vsj simulat fig-4.15
vsj linearize --friction wrong
vsj linearize --q=-1cm --bogus
vsj params --check my_own.toml           # correct: parsed only, the reader's own file
vsj verify nowhere
make no-such-target
vsj sweep SPEC.toml [--motors dc] [--method sobol|morris]
```

With `--motors dc` or `--friction wrong`; `vsj fit planetery` is not a command, while
`--friction viscous` (`vsj linearize`) is right.

```python
raise RuntimeError("a broken snippet")
```

```toml
[planetary]
ring_inertia = { value = "6.47e-5 kg", source = "an inertia in kg" }
```

`vsj.no_such_module`, `Result.no_such_method()`, `ElasticElement(..., no_such_keyword=1)`,
`src/vsj/no_such_file.py`, `engine/c/no_such_file.c`, `no_such_file.py`,
`vsj_no_such_function`; but `Result.to_xarray()`, `vsj.wrist.build_wrist`,
`engine/c/laws.c` and `vsj_step` exist.

![a figure](docs/no-such-figure.png)
"""


def _each_names(problems: list[str], expected: list[str]) -> None:
    """One problem per expected fragment, each naming its own, in order."""
    assert len(problems) == len(expected), "\n".join(problems)
    for fragment, problem in zip(expected, problems):
        assert fragment in problem, problem


def test_the_checks_find_each_kind_of_mistake(tmp_path, monkeypatch):
    """Each check finds its mistake in `FLAWED` and flags none of its correct lines, so
    that a README test that passes has checked something."""
    monkeypatch.chdir(tmp_path)
    problems, log = code_block_problems(FLAWED, tmp_path, "FLAWED")
    expected = ["`vsj simulat`: no such command",
                "--friction wrong: allowed",
                "`vsj linearize` has no option --bogus",
                "`vsj verify nowhere`: exit code 2",
                "no make target 'no-such-target'",
                "`vsj sweep` has no option --motors",
                "the Python block fails",
                "ring_inertia"]
    _each_names(problems, expected)
    assert "ran: vsj scenarios" in log[0] and "parsed only (its input my_own.toml" in log[4]

    problems = prose_problems(FLAWED, "FLAWED")
    expected = ["`--motors dc`: no such option of the commands this section shows",
                "`--friction wrong`: --friction wrong: allowed",
                "`vsj fit planetery`: no such command"]
    _each_names(problems, expected)

    problems = name_problems(FLAWED, "FLAWED")
    expected = ["`vsj.no_such_module`: vsj has no 'no_such_module'",
                "`Result.no_such_method()`: Result has no 'no_such_method'",
                "takes no keyword no_such_keyword",
                "`src/vsj/no_such_file.py`: no such file",
                "`engine/c/no_such_file.c`: no such file",
                "`no_such_file.py`: no such source file",
                "`vsj_no_such_function`: not in the C sources"]
    _each_names(problems, expected)

    assert figure_problems(FLAWED, "FLAWED") == [
        "FLAWED shows docs/no-such-figure.png, which does not exist",
        "FLAWED shows docs/no-such-figure.png, which `make figures` does not write"]
