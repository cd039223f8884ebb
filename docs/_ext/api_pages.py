"""The API reference's pages: one reST page per public module of vsj, written before the
build reads its sources (docs/conf.py calls `write_pages`).

What a page documents is read from the module's source, not from its namespace: every
public module-level class and function (a name without a leading ``_``) and every
module-level value with a ``#:`` comment. Autosummary's recursive mode finds modules and
members through the package's attributes instead, and vsj has attributes that shadow
submodules (``vsj.simulate`` is the function as well as the package), which it then
documents as the function and loses the package. tests/test_docs.py checks that every
public definition has its entry (`module_pages`), and tools/check_site.py that each
one's anchor is on the built page.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "vsj"


@dataclass(frozen=True)
class ModulePage:
    """What one module's page documents: classes, functions and documented values by
    name, and the public submodules of a package."""

    name: str
    classes: tuple[str, ...]
    functions: tuple[str, ...]
    data: tuple[str, ...]
    submodules: tuple[str, ...]

    def text(self) -> str:
        """The page as reST."""
        title = self.name.replace("_", r"\_")
        lines = [title, "=" * len(title), "", f".. automodule:: {self.name}",
                 "   :no-members:", "", f".. currentmodule:: {self.name}", ""]
        if self.submodules:
            lines += [".. rubric:: Modules", "", ".. toctree::", "   :maxdepth: 1", ""]
            lines += [f"   {m}" for m in self.submodules] + [""]
        if self.classes or self.functions:
            lines += [".. rubric:: Summary", "", ".. autosummary::", "   :nosignatures:", ""]
            lines += [f"   {n}" for n in self.classes + self.functions] + [""]
        for name in self.classes:
            lines += [f".. autoclass:: {name}", "   :members:", "   :show-inheritance:", ""]
        for name in self.functions:
            lines += [f".. autofunction:: {name}", ""]
        for name in self.data:
            lines += [f".. autodata:: {name}", ""]
        return "\n".join(lines)


def _module_name(path: Path, package: Path) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_public(name: str) -> bool:
    return all(not part.startswith("_") for part in name.split("."))


def _documented_values(tree: ast.Module, lines: list[str]) -> list[str]:
    """Module-level names assigned once with a ``#:`` comment on the line above."""
    names = []
    for node in tree.body:
        target = None
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
        elif isinstance(node, ast.AnnAssign):
            target = node.target
        if isinstance(target, ast.Name) and not target.id.startswith("_") \
                and node.lineno >= 2 and lines[node.lineno - 2].lstrip().startswith("#:"):
            names.append(target.id)
    return list(dict.fromkeys(names))


def module_pages(package: Path = PACKAGE) -> list[ModulePage]:
    """A page for every public module of the package (no part of its dotted name starts
    with ``_``; ``__main__`` is no API), in name order."""
    sources = {_module_name(p, package): p for p in package.rglob("*.py")}
    public = sorted(n for n in sources if _is_public(n))
    pages = []
    for name in public:
        source = sources[name].read_text()
        tree = ast.parse(source)
        defs = [n for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef,
                                                       ast.AsyncFunctionDef))
                and not n.name.startswith("_")]
        children = tuple(n for n in public if n.rpartition(".")[0] == name)
        pages.append(ModulePage(
            name,
            tuple(d.name for d in defs if isinstance(d, ast.ClassDef)),
            tuple(d.name for d in defs if not isinstance(d, ast.ClassDef)),
            tuple(_documented_values(tree, source.splitlines())),
            children))
    return pages


def write_pages(out: Path, package: Path = PACKAGE) -> list[Path]:
    """Write every page into ``out`` (a file is rewritten only when its text changed, so
    that an unchanged module is not read again) and remove pages of modules that are
    gone. Returns the pages' paths."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for page in module_pages(package):
        path = out / f"{page.name}.rst"
        text = page.text()
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        written.append(path)
    for stale in set(out.glob("*.rst")) - set(written):
        stale.unlink()
    return written
