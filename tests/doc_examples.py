"""Checking the examples that the documentation shows (README.md's code blocks, the
docstrings' ``::`` blocks): shared by tests/test_readme.py and
tests/test_documented_api.py."""

from __future__ import annotations

import ast
import json
import re
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "src" / "vsj"


def param_stand_in() -> str:
    """A parameter file for an example that names one it does not show."""
    return 'extends = "second_prototype"\n'


def covariance_stand_in(varied: set[str]) -> str:
    """A covariance file (what ``vsj fit wrist --json`` writes) for an example that names
    one it does not show: one parameter the example does not vary, 1 % standard error."""
    from vsj import params

    bundled = params.default()
    name = next(k for k, v in bundled.values.items() if k not in varied and v > 0)
    value = bundled[name]
    return json.dumps({"names": [name], "parameters": {name: value},
                       "covariance": [[(0.01 * value) ** 2]]})


def check_toml(text: str, origin: str, cwd: Path) -> None:
    """Load a TOML example with the loader of the file it shows, raising what the loader
    raises: a sweep file (its signal and metric names checked against the scenario as
    ``vsj sweep`` checks them before a run; files it names that ``cwd`` does not hold get
    stand-ins), a design file (its base parameter set loaded), an identification
    experiment, a scenario (each case prepared), or else a
    parameter file (over the bundled set when it does not say what it extends)."""
    table = tomllib.loads(text)
    if "sweep" in table:
        from vsj.sweep import spec as sweep_spec
        from vsj.sweep.runner import describe, job_for

        given = table["sweep"].get("params")
        if given and not (cwd / given).exists():
            (cwd / given).write_text(param_stand_in())
        covariance = table.get("covariance", {}).get("file")
        if covariance and not (cwd / covariance).exists():
            (cwd / covariance).write_text(covariance_stand_in(set(table.get("vary", {}))))
        path = cwd / (re.sub(r"\W+", "-", origin) + ".sweep.toml")
        path.write_text(text)
        describe(job_for(sweep_spec.load(path)))
    elif "objectives" in table:
        from vsj.design import loads, optimise

        optimise.problem_for(loads(text, origin, cwd))
    elif "experiment" in table:
        from vsj.identification import wrist_experiment

        wrist_experiment.from_table(table, origin)
    elif "network" in table or "cases" in table:
        from vsj import params, scenario

        scen = scenario.loads(text, origin)
        for case in scen.cases:
            scenario.prepare_case(scen, case, params.default())
    else:
        from vsj import params

        params.loads(text if "extends" in table else param_stand_in() + text, origin,
                     base=cwd)


@dataclass(frozen=True)
class Example:
    """A ``::`` block of a docstring: where it is, its text (``...`` lines, which stand
    for "and so on", removed) and what it is (``toml``, ``python`` or ``text``)."""

    where: str
    text: str
    kind: str


def _kind(text: str) -> str:
    try:
        tomllib.loads(text)
        return "toml"
    except tomllib.TOMLDecodeError:
        pass
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return "text"
    # a bare expression (a list of symbols, say) is notation, not an example to run
    return "python" if any(not isinstance(s, ast.Expr) for s in tree.body) else "text"


def docstring_examples() -> list[Example]:
    """Every ``::`` block of a docstring in ``src/vsj``, read from the source files."""
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        module = ".".join(path.relative_to(SOURCE.parent).with_suffix("").parts)
        module = module.removesuffix(".__init__")
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                     ast.AsyncFunctionDef)):
                continue
            doc = ast.get_docstring(node, clean=True)
            if not doc:
                continue
            owner = module if isinstance(node, ast.Module) else f"{module}.{node.name}"
            for m in re.finditer(r"::\n\n((?:(?: {4}.*)?\n)+)", doc + "\n"):
                lines = [line for line in textwrap.dedent(m.group(1)).splitlines()
                         if line.strip() != "..."]
                text = "\n".join(lines).strip("\n") + "\n"
                line = doc.count("\n", 0, m.start()) + 1
                found.append(Example(f"{owner} (docstring, line {line})", text, _kind(text)))
    return found
