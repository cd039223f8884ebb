"""Check the built documentation site offline (``make docs`` runs it after the build).

    python tools/check_site.py docs/_build/html

Three checks on the HTML that Sphinx wrote, none of which goes on the network:

* **Internal links.** Every ``href`` and ``src`` of every page that points inside the
  site names a file that exists, and its ``#fragment`` an ``id`` (or ``name``) on that
  page. Sphinx's own ``linkcheck`` builder would fetch every external link as well.
* **Nothing loaded from outside.** No script, style sheet, image or frame comes from
  another host (``http:``, ``https:`` or ``//``): the site must work offline. Plain
  links to other sites (a reader may follow them) are allowed.
* **Coverage.** Every public definition of the package (`public_names`: what
  tests/test_public_docs.py requires a docstring of) has its anchor in the API
  reference, and every command of ``vsj`` (`command_paths`) its section in the
  command-line reference.

Prints one line per problem and exits 1 if there is any, else prints what it checked.
"""

from __future__ import annotations

import argparse
import ast
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "vsj"
#: Attributes that load a resource into the page (as opposed to a link to follow).
LOADING = {("script", "src"), ("img", "src"), ("iframe", "src"), ("source", "src"),
           ("link", "href"), ("embed", "src"), ("object", "data")}
#: ``<link rel=...>`` kinds that are not loaded by the browser (navigation hints).
NOT_LOADED_RELS = {"index", "search", "next", "prev", "canonical", "author", "license",
                   "top", "up", "help", "copyright"}


class _Page(HTMLParser):
    """The ids and the outgoing references of one HTML page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.refs: list[tuple[str, str, str, bool]] = []  # (tag, attribute, url, loads)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        for key in ("id", "name"):
            if attrs.get(key) and (key == "id" or tag == "a"):
                self.ids.add(attrs[key])
        for attribute in ("href", "src", "data"):
            url = attrs.get(attribute)
            if not url:
                continue
            loads = (tag, attribute) in LOADING
            if tag == "link":
                rels = set((attrs.get("rel") or "").lower().split())
                loads = not rels or not rels <= NOT_LOADED_RELS
            self.refs.append((tag, attribute, url, loads))


def read_pages(site: Path) -> dict[Path, _Page]:
    """Every HTML page of the site, parsed."""
    pages = {}
    for path in sorted(site.rglob("*.html")):
        page = _Page()
        page.feed(path.read_text(encoding="utf-8", errors="replace"))
        pages[path.resolve()] = page
    return pages


def link_problems(site: Path, pages: dict[Path, _Page] | None = None) -> list[str]:
    """Broken internal links and anchors, and resources loaded from another host."""
    site = site.resolve()
    pages = read_pages(site) if pages is None else pages
    problems = []
    for path, page in pages.items():
        where = path.relative_to(site)
        for tag, attribute, url, loads in page.refs:
            parts = urlsplit(url)
            if parts.scheme in ("mailto", "javascript", "data", "tel"):
                continue
            if parts.scheme or url.startswith("//"):
                if loads:
                    problems.append(f"{where}: <{tag} {attribute}={url!r}> loads from "
                                    f"another host (the site must work offline)")
                continue
            target = path if not parts.path else (path.parent / unquote(parts.path)).resolve()
            if parts.path.endswith("/") or target.is_dir():
                target = target / "index.html"
            if not target.is_relative_to(site):
                problems.append(f"{where}: {url!r} points outside the site")
                continue
            if not target.exists():
                problems.append(f"{where}: {url!r}: no such file {target.relative_to(site)}")
                continue
            fragment = unquote(parts.fragment)
            if fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else set()
                if fragment not in ids:
                    problems.append(f"{where}: {url!r}: {target.relative_to(site)} has no "
                                    f"anchor #{fragment}")
    return problems


def public_names(package: Path = PACKAGE) -> list[str]:
    """Dotted names of the package's public definitions: module-level functions and
    classes, and the methods and properties of such classes, of every module whose path
    has no part starting with ``_`` (``__init__`` counts as its package)."""
    names = []
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts):
            continue
        module = ".".join(parts)
        for node in ast.parse(path.read_text()).body:
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) \
                    or node.name.startswith("_"):
                continue
            names.append(f"{module}.{node.name}")
            if isinstance(node, ast.ClassDef):
                names += [f"{module}.{node.name}.{m.name}" for m in node.body
                          if isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef))
                          and not m.name.startswith("_")]
    return names


def api_problems(site: Path, pages: dict[Path, _Page] | None = None) -> list[str]:
    """Public definitions without an anchor on their module's page of the API reference."""
    site = site.resolve()
    pages = read_pages(site) if pages is None else pages
    generated = site / "reference" / "generated"
    problems = []
    for name in public_names():
        module = name
        while module and not (generated / f"{module}.html").exists():
            module = module.rpartition(".")[0]
        page = pages.get((generated / f"{module}.html").resolve()) if module else None
        if page is None or name not in page.ids:
            problems.append(f"API reference: no entry for {name}"
                            + ("" if module else " (no page for its module)"))
    return problems


def command_paths() -> list[list[str]]:
    """Every command of ``vsj``, as the words after ``vsj`` (``["fit", "wrist"]``)."""
    from vsj.cli import build_parser

    def walk(parser, path):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            return [path]
        found = [path] if path else []
        for name, sub in subs[0].choices.items():
            found += walk(sub, [*path, name])
        return found

    return walk(build_parser(), [])


def cli_problems(site: Path, pages: dict[Path, _Page] | None = None) -> list[str]:
    """Commands without their section in the command-line reference."""
    site = site.resolve()
    pages = read_pages(site) if pages is None else pages
    page = pages.get((site / "reference" / "cli.html").resolve())
    if page is None:
        return ["CLI reference: reference/cli.html was not built"]
    return [f"CLI reference: no section for `vsj {' '.join(path)}`"
            for path in command_paths() if "-".join(["vsj", *path]) not in page.ids]


def main(argv=None) -> int:
    """Run every check on the site directory given; 0 if all pass, 1 otherwise."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("site", type=Path, help="the built HTML (docs/_build/html)")
    args = parser.parse_args(argv)
    if not (args.site / "index.html").is_file():
        print(f"{args.site}: no index.html (build the site first: make docs)")
        return 1
    pages = read_pages(args.site)
    problems = (link_problems(args.site, pages) + api_problems(args.site, pages)
                + cli_problems(args.site, pages))
    for problem in problems:
        print(problem)
    links = sum(len(p.refs) for p in pages.values())
    print(f"checked {len(pages)} pages, {links} links and resources, "
          f"{len(public_names())} public names, {len(command_paths())} commands: "
          f"{len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
