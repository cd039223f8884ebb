"""The package's layers (issue 32): no import circle among vsj's modules, and the
compiled binding `vsj._core` a leaf that imports nothing of vsj.

The module graph is read from the sources: each module's imports at module level
(those inside functions run later, on demand, and cannot make an import fail half
way). A package's ``__init__`` counts as a module like any other; the implicit import
of a parent package is not an edge (Python runs it first, whatever the module).
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "src"
PACKAGE = ROOT / "vsj"


def modules() -> dict[str, Path | None]:
    """Every module of vsj by dotted name (the compiled binding without a source)."""
    found: dict[str, Path | None] = {"vsj._core": None}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def module_imports(name: str, path: Path, known) -> set[str]:
    """The vsj modules that module ``name`` imports at module level (``if`` blocks
    included, but for ``if TYPE_CHECKING:``, which never runs)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    out = set()
    todo = list(ast.parse(path.read_text()).body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) \
                and node.test.id == "TYPE_CHECKING":
            todo += node.orelse
        elif isinstance(node, (ast.If, ast.Try)):
            todo += node.body + node.orelse + getattr(node, "finalbody", [])
            for handler in getattr(node, "handlers", []):
                todo += handler.body
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "vsj"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
                base = ".".join(base + ([node.module] if node.module else []))
            elif (node.module or "").split(".")[0] == "vsj":
                base = node.module
            else:
                continue
            for alias in node.names:  # a submodule, or a name of the module `base`
                sub = f"{base}.{alias.name}"
                out.add(sub if sub in known else base)
    return {m for m in out if m in known and m != name}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def graph_of(known) -> dict[str, set[str]]:
    return {name: (module_imports(name, path, known) if path else set())
            for name, path in known.items()}


def test_no_module_of_vsj_imports_itself_round_a_circle():
    circles = cycles(graph_of(modules()))
    assert circles == [], "import circles: " + "; ".join(" -> ".join(c) for c in circles)


def test_the_checker_finds_a_circle(tmp_path):
    graph = {"vsj.a": {"vsj.b"}, "vsj.b": {"vsj.c"}, "vsj.c": {"vsj.a"}, "vsj.d": {"vsj.a"}}
    assert cycles(graph) == [["vsj.a", "vsj.b", "vsj.c"]]
    # and reads one from sources: a package whose module imports it back
    pkg = tmp_path / "vsj" / "p"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .m import f\n")
    (pkg / "m.py").write_text("if True:\n    from . import g\ndef f():\n    import os\n"
                              "if TYPE_CHECKING:\n    from . import h\n")
    (pkg / "h.py").write_text("")
    known = {"vsj.p": pkg / "__init__.py", "vsj.p.m": pkg / "m.py", "vsj.p.h": pkg / "h.py"}
    assert module_imports("vsj.p.m", pkg / "m.py", known) == {"vsj.p"}  # not h: never run
    assert cycles(graph_of(known)) == [["vsj.p", "vsj.p.m"]]


def test_the_binding_is_a_leaf():
    """`vsj._core` holds no physics and imports nothing of vsj; the laws, the network
    and the engine import it."""
    text = (PACKAGE / "_core.c").read_text()
    assert "PyImport_Import" not in text and "PyImport_ImportModule" not in text
    users = {name for name, deps in graph_of(modules()).items() if "vsj._core" in deps}
    assert {"vsj.springs", "vsj.friction", "vsj.engine.core", "vsj.engine.plan"} <= users


def test_every_page_is_made_by_vsj_pages():
    """One look: only `vsj.pages` writes a page's shell (doctype, head, style sheet);
    the datasheet, reproduction, sweep summary, identification report and the FMU's
    documentation give it their body."""
    shells = sorted(str(p.relative_to(ROOT)) for p in PACKAGE.rglob("*.py")
                    if p.name != "pages.py" and ("<html" in (text := p.read_text()).lower()
                                                 or "<!doctype" in text.lower()))
    assert shells == [], f"pages with their own HTML shell: {shells}"


def test_each_law_is_one_line_of_the_engines_table():
    """The friction and spring laws' codes and names come from engine/c/vsj_layout.h's
    tables (through `vsj._core.LAYOUT`): Python declares none of its own, and the engine
    evaluates every law of its tables and refuses a code past them."""
    import numpy as np

    from vsj import _core, friction, springs

    assert tuple(friction.LAWS) == _core.LAYOUT["friction_laws"]
    assert tuple(springs.MODELS) == _core.LAYOUT["spring_laws"]
    assert list(friction.LAWS.values()) == list(range(len(friction.LAWS)))
    for law in friction.RUN_LAWS:  # (a contact's force needs its penetration too)
        torque = friction.torque(law, np.array([-0.3, 0.2]), viscous=0.01, stiction=0.02,
                                 sharpness=10.0, width=0.1)
        assert np.all(np.isfinite(torque)) and torque[0] < 0 < torque[1], law
    out = np.empty((1, 4))
    for code in springs.MODELS.values():
        _core.spring_law(code, np.full(9, 0.01) + np.eye(9)[6], np.array([0.01]), 0.0, out)
    import pytest

    with pytest.raises(ValueError, match="unknown friction law"):
        _core.friction_torque(len(friction.LAWS), 0.0, 0.0, 1.0, 1.0, np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="unknown spring law"):
        _core.spring_law(len(springs.MODELS), np.zeros(9), np.zeros(1), 0.0, out)
