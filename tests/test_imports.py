"""Imports inside functions (issue 32): each one says why it is not at module level, and
what ``import vsj`` and ``import vsj.cli`` (the start of every ``vsj`` command) load.

An import inside a function is kept only where moving it up would add a heavy library
to a common command's start (``# lazy: <reason>``) or close an import circle
(``# circle: <reason>``). The tag sits on the import's own line, or on the comment line
that heads a run of consecutive imports.
"""

import ast
import json
import subprocess
import sys
from pathlib import Path

from test_architecture import graph_of, modules

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "vsj"
TAGS = ("# lazy: ", "# circle: ")
#: being reworked (issue 32): their imports are checked once the rework lands
REWORKED: set[str] = set()
#: what ``import vsj`` and ``import vsj.cli`` must not load: each adds a noticeable
#: part of a second to every command's start and no common command needs it at once
HEAVY = ("matplotlib", "xarray", "dask", "scipy", "scipy.optimize", "pint", "zarr", "SALib",
         "control", "pymoo")


def _reworked(path: Path) -> bool:
    rel = path.relative_to(PACKAGE).as_posix()
    return any(rel == r or r.endswith("/") and rel.startswith(r) for r in REWORKED)


def _tag(line: str) -> str | None:
    """The tag of a source line (None if it has none or gives no reason after it)."""
    for tag in TAGS:
        at = line.find(tag)
        if at >= 0 and line[at + len(tag):].strip():
            return tag
    return None


def function_imports(source: str) -> list[tuple[ast.stmt, str | None]]:
    """Every import statement inside a function body of ``source``, with its tag (from
    its own lines, or from the comment heading its run of consecutive imports)."""
    lines = source.splitlines()
    found = []

    def walk(node, inside: bool):
        body_imports = []
        for child in ast.iter_child_nodes(node):
            here = inside or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
            if here and isinstance(child, (ast.Import, ast.ImportFrom)):
                body_imports.append(child)
            walk(child, here)
        for k, stmt in enumerate(body_imports):
            tag = next((t for t in map(_tag, lines[stmt.lineno - 1:stmt.end_lineno]) if t),
                       None)
            first = stmt
            j = k
            while j > 0 and body_imports[j - 1].end_lineno == first.lineno - 1:
                j -= 1
                first = body_imports[j]
            if tag is None and first.lineno >= 2:
                above = lines[first.lineno - 2].strip()
                tag = _tag(above) if above.startswith("#") else None
            found.append((stmt, tag))

    walk(ast.parse(source), False)
    return found


def _dotted(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _targets(stmt, name: str, path: Path, known) -> set[str]:
    """The vsj modules an import statement of module ``name`` names."""
    if isinstance(stmt, ast.Import):
        return {a.name for a in stmt.names if a.name in known}
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if stmt.level:
        base = ".".join(package[:len(package) - (stmt.level - 1)]
                        + ([stmt.module] if stmt.module else []))
    else:
        base = stmt.module or ""
    out = {f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in stmt.names}
    return out & set(known)


def _reaches(graph, start: str, goal: str) -> bool:
    seen, todo = set(), [start]
    while todo:
        v = todo.pop()
        if v == goal:
            return True
        if v not in seen:
            seen.add(v)
            todo += graph.get(v, ())
    return False


def sources():
    for path in sorted(PACKAGE.rglob("*.py")):
        if not _reworked(path):
            yield path


def test_every_import_inside_a_function_says_why():
    untagged = [f"{path.relative_to(PACKAGE)}:{stmt.lineno}"
                for path in sources()
                for stmt, tag in function_imports(path.read_text()) if tag is None]
    assert untagged == [], ("imports inside functions without a '# lazy: <reason>' or "
                            "'# circle: <reason>' comment: " + ", ".join(untagged))


def test_a_circle_tag_names_a_real_circle_and_nothing_lazy_is_loaded_already():
    """``# circle:`` only where the imported module does import this one (at module level,
    through any chain); no lazy import of a vsj module that the same module imports at
    module level anyway (it would save nothing)."""
    known = modules()
    graph = graph_of(known)
    wrong = []
    for path in sources():
        name = _dotted(path)
        for stmt, tag in function_imports(path.read_text()):
            targets = _targets(stmt, name, path, known) - {name}
            where = f"{path.relative_to(PACKAGE)}:{stmt.lineno}"
            if tag == "# circle: " and not any(_reaches(graph, t, name) for t in targets):
                wrong.append(f"{where} is tagged circle, but none of {sorted(targets)} "
                             f"imports {name}")
            if tag == "# lazy: " and targets and targets <= graph[name]:
                wrong.append(f"{where} is lazy, but {name} imports {sorted(targets)} at "
                             "module level")
    assert wrong == [], "\n".join(wrong)


def test_the_checker_finds_an_untagged_import():
    source = (
        "def f():\n"
        "    import os\n"
        "def g():\n"
        "    import numpy  # lazy: a reason\n"
        "def h():\n"
        "    # circle: a reason\n"
        "    from . import a\n"
        "    from . import (b,\n"
        "                   c)\n"
        "\n"
        "    from . import d\n"
        "def k():\n"
        "    import zarr  # lazy:\n"
        "import json\n")
    tags = {stmt.lineno: tag for stmt, tag in function_imports(source)}
    assert tags == {2: None, 4: "# lazy: ", 7: "# circle: ", 8: "# circle: ", 11: None,
                    13: None}


def _loaded_after(*statements: str) -> list[list[str]]:
    """The modules of `HEAVY` loaded after each statement, run in turn in one fresh
    interpreter."""
    code = ("import json, sys\nout = []\n"
            + "".join(f"{s}\nout.append([m for m in {HEAVY!r} if m in sys.modules])\n"
                      for s in statements)
            + "print(json.dumps(out))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    return json.loads(done.stdout)


def test_importing_vsj_or_its_command_line_loads_no_heavy_library():
    # the last statement checks the probe: vsj.characteristics needs scipy.optimize
    plain, cli, control = _loaded_after("import vsj", "import vsj.cli",
                                        "import vsj.characteristics")
    assert plain == [], f"import vsj loads {plain}"
    assert cli == [], f"import vsj.cli loads {cli}"
    assert {"scipy", "scipy.optimize"} <= set(control)


def test_a_scenario_without_an_environment_loads_none_of_its_modules():
    """`vsj simulate` of a scenario without [environment] (most are) imports neither
    `vsj.environment` nor `vsj.safety`; a scenario with one does (checks the probe)."""
    example = sorted((PACKAGE.parents[1] / "examples" / "environment").glob("*.toml"))[0]
    prepared = ("from vsj import params, scenario\n"
                "s = scenario.load({name!r})\n"
                "scenario.prepare_case(s, s.cases[0], params.default())")
    code = ("import json, sys\n" + prepared.format(name="fig-4.15") + "\n"
            "out = [sorted(m for m in sys.modules if m.startswith(('vsj.environment', "
            "'vsj.safety')))]\n" + prepared.format(name=str(example)) + "\n"
            "out.append('vsj.environment' in sys.modules)\nprint(json.dumps(out))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    plain, probe = json.loads(done.stdout)
    assert plain == [], f"a scenario without [environment] loads {plain}"
    assert probe
