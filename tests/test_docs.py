"""The documentation site's sources, checked without building it (`make docs` builds it,
runs its examples and checks the built pages with tools/check_site.py).

* **API reference**: every public module has a docstring and a page
  (docs/_ext/api_pages.py), every public class and function a directive on its module's
  page, and every page is reached from the reference's index.
* **CLI reference**: generated from `vsj.cli.build_parser` with every subcommand, and
  every command has a help text for its section.
* **Examples**: every script under examples/ compiles; the gallery scripts have the
  title sphinx-gallery needs, and each one is in a table of contents.
* **Pages**: every Markdown page of docs/ is checked as README.md is
  (tests/readme_checks.py): its commands exist and the cheap ones run, its Python and
  TOML blocks run and load, the names and files it mentions exist; its links to other
  pages name files that exist.
* **The checkers themselves** find each kind of mistake on a small site made here.
"""

from __future__ import annotations

import ast
import importlib.util
import re
import sys
from pathlib import Path

import pytest

from readme_checks import code_block_problems, command_paths, name_problems, parser_at, \
    prose_problems
from vsj.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = ROOT / "examples"
PAGES = sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)


def _load(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


api_pages = _load(DOCS / "_ext" / "api_pages.py", "api_pages")
check_site = _load(ROOT / "tools" / "check_site.py", "check_site")


# -- API reference ------------------------------------------------------------------------

def _directives(text: str) -> set[str]:
    return set(re.findall(r"^\.\. auto(?:class|function|data|exception):: (\S+)$", text, re.M))


def test_every_public_name_is_on_its_module_page():
    pages = {p.name: p for p in api_pages.module_pages()}
    missing = []
    for name in check_site.public_names():
        module, _, attribute = name.rpartition(".")
        if module in pages:  # a module-level definition
            if attribute not in _directives(pages[module].text()):
                missing.append(name)
        elif module.rpartition(".")[0] not in pages:  # not a method of a documented class
            missing.append(f"{name} (no page for its module)")
    assert not missing, "public names missing from the API reference:\n" + "\n".join(missing)


def test_every_module_page_is_reached_and_has_a_docstring():
    pages = {p.name: p for p in api_pages.module_pages()}
    index = (DOCS / "reference" / "api.rst").read_text()
    reached, todo = set(), re.findall(r"^\s+generated/(\S+)$", index, re.M)
    while todo:
        name = todo.pop()
        if name not in reached:
            reached.add(name)
            todo += list(pages[name].submodules)
    assert reached == set(pages), f"pages no table of contents reaches: {set(pages) - reached}"
    for name in pages:
        spec = importlib.util.find_spec(name)
        assert ast.get_docstring(ast.parse(Path(spec.origin).read_text())), \
            f"module {name} has no docstring (its page would be empty)"


def test_pages_are_read_from_the_source_not_the_namespace(tmp_path):
    """A package whose function shadows a submodule of the same name (as ``vsj.simulate``
    does), a private module, a re-export and documented values: each page documents what
    its module defines."""
    package = tmp_path / "pkg"
    (package / "run").mkdir(parents=True)
    (package / "__init__.py").write_text('"""Pkg."""\nfrom .run import run\n')
    (package / "run" / "__init__.py").write_text(
        '"""Run."""\n#: The default.\nDEFAULT = 1\nUNDOCUMENTED = 2\n'
        'def run():\n    """Run."""\nclass Result:\n    """Result."""\ndef _helper():\n    pass\n')
    (package / "_private.py").write_text('"""Private."""\ndef visible():\n    """No."""\n')
    pages = {p.name: p for p in api_pages.module_pages(package)}
    assert set(pages) == {"pkg", "pkg.run"}
    assert pages["pkg"].submodules == ("pkg.run",) and _directives(pages["pkg"].text()) == set()
    assert _directives(pages["pkg.run"].text()) == {"Result", "run", "DEFAULT"}
    written = api_pages.write_pages(tmp_path / "out", package)
    (tmp_path / "out" / "pkg.gone.rst").write_text("stale")
    api_pages.write_pages(tmp_path / "out", package)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in written)


# -- CLI reference --------------------------------------------------------------------------

def test_cli_reference_is_the_parser_with_every_command():
    text = (DOCS / "reference" / "cli.rst").read_text()
    assert re.search(r"^\.\. argparse::\n   :module: vsj\.cli\n   :func: build_parser$", text,
                     re.M), "the CLI reference is not generated from vsj.cli.build_parser"
    assert ":nosubcommands:" not in text and ":path:" not in text
    parser = build_parser()
    paths = command_paths(parser)
    assert len(paths) >= 20 and ["fit", "wrist"] in paths
    for path in paths:
        sub = parser_at(parser, path)
        assert sub.description or any(
            path[-1] in (a.choices or {}) and any(c.dest == path[-1] and c.help
                                                  for c in a._choices_actions)
            for a in parser_at(parser, path[:-1])._actions
            if hasattr(a, "_choices_actions")), f"`vsj {' '.join(path)}` has no help text"
    # the built-page check names the section of each command the same way
    assert [p for p in check_site.command_paths() if len(p) == len(set(p))] \
        and all(p in check_site.command_paths() for p in paths)


# -- examples ---------------------------------------------------------------------------------

def _gallery_dirs() -> list[Path]:
    return sorted(p.parent for p in EXAMPLES.glob("*/README.rst"))


def test_gallery_configuration_names_each_gallery():
    conf = (DOCS / "conf.py").read_text()
    galleries = _gallery_dirs()
    assert {p.name for p in galleries} >= {"getting_started", "guide"}
    for gallery in galleries:
        assert f'"examples" / "{gallery.name}"' in conf, f"conf.py does not run {gallery}"


@pytest.mark.parametrize("script", sorted(EXAMPLES.rglob("*.py")),
                         ids=lambda p: str(p.relative_to(EXAMPLES)))
def test_example_scripts_compile(script):
    compile(script.read_text(), str(script), "exec")
    if script.parent in _gallery_dirs():
        doc = ast.get_docstring(ast.parse(script.read_text())) or ""
        title, _, rule = doc.partition("\n")
        assert title.strip() and re.fullmatch(r"=+", rule.split("\n")[0].strip()) \
            and len(rule.split("\n")[0].strip()) >= len(title.strip()), \
            f"{script}: sphinx-gallery needs a docstring that starts with a title over ==="


def test_getting_started_lists_every_script():
    toc = (DOCS / "getting-started" / "index.md").read_text()
    for script in sorted((EXAMPLES / "getting_started").glob("*.py")):
        assert f"examples/{script.stem}\n" in toc, f"{script.name} is in no table of contents"


# -- pages --------------------------------------------------------------------------------------

def without_directives(text: str) -> str:
    """The page with the bodies of its MyST directives (```{toctree}, ```{literalinclude}:
    document names and options, not commands) blanked, line numbers kept."""
    return re.sub(r"^```\{.*?^```[ \t]*$", lambda m: "\n" * m.group(0).count("\n"), text,
                  flags=re.S | re.M)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_page_commands_snippets_and_names(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text, origin = without_directives(page.read_text()), str(page.relative_to(ROOT))
    problems, log = code_block_problems(text, tmp_path, origin)
    problems += prose_problems(text, origin) + name_problems(text, origin)
    print("\n".join(log))
    for target in re.findall(r"\]\(([^)#\s]+\.(?:md|rst))(?:#[^)]*)?\)", text):
        generated = "examples/" in target  # a gallery page, written by the build
        if not generated and not (page.parent / target).resolve().is_file():
            problems.append(f"{origin}: link to {target}, which does not exist")
    assert not problems, "\n".join(problems)


def test_pages_link_to_gallery_pages_that_the_gallery_makes():
    scripts = {f"{p.parent.name}/{p.stem}" for g in _gallery_dirs() for p in g.glob("*.py")}
    made = {"getting_started": "getting-started/examples", "guide": "user-guide/examples"}
    for page in PAGES:
        for target in re.findall(r"\]\(((?:\.\./)*[\w/-]*examples/[\w-]+)\.rst\)", page.read_text()):
            full = (page.parent / target).resolve().relative_to(DOCS.resolve()).as_posix()
            sources = {f"{made[k]}/{s.split('/')[1]}" for s in scripts
                       for k in made if s.startswith(k + "/")}
            assert full in sources | {"user-guide/examples/index",
                                      "getting-started/examples/index"}, \
                f"{page.relative_to(DOCS)} links to {target}.rst, which no example makes"


# -- the built-site checker -------------------------------------------------------------------

def test_site_checker_finds_each_kind_of_problem(tmp_path):
    site = tmp_path / "html"
    (site / "sub").mkdir(parents=True)
    (site / "index.html").write_text(
        '<html><head><link rel="stylesheet" href="style.css">'
        '<script src="https://cdn.example.org/x.js"></script>'
        '<link rel="canonical" href="https://example.org/"></head><body>'
        '<h1 id="top">t</h1><a href="#top">ok</a><a href="sub/page.html#here">ok</a>'
        '<a href="sub/page.html#nowhere">bad anchor</a><a href="missing.html">bad file</a>'
        '<a href="https://example.org/docs">a plain link out: allowed</a>'
        '<img src="//cdn.example.org/i.png"></body></html>')
    (site / "style.css").write_text("")
    (site / "sub" / "page.html").write_text('<p id="here"><a href="../index.html#top">up</a></p>')
    problems = check_site.link_problems(site)
    assert len(problems) == 4, "\n".join(problems)
    for fragment in ("x.js'> loads from another host", "has no anchor #nowhere",
                     "no such file missing.html", "i.png'> loads from another host"):
        assert any(fragment in p for p in problems), (fragment, problems)


def test_site_checker_finds_missing_reference_entries(tmp_path):
    site = tmp_path / "html"
    (site / "reference" / "generated").mkdir(parents=True)
    names = check_site.public_names()
    assert "vsj.simulate.driver.run_plan" in names and "vsj.params.Parameters.hash" in names
    listed = [n for n in names if n != "vsj.params.Parameters.hash"]
    # a page for each module and class, holding the entries of everything under it
    for module in {n.rsplit(".", 1)[0] for n in names} | {"vsj"}:
        (site / "reference" / "generated" / f"{module}.html").write_text(" ".join(
            f'<dt id="{n}"></dt>' for n in listed if n.startswith(f"{module}.")
            or n == module))
    (site / "reference" / "cli.html").write_text(
        " ".join(f'<section id="{"-".join(["vsj", *p])}">' for p in check_site.command_paths()
                 if p != ["fit", "wrist"]))
    pages = check_site.read_pages(site)
    assert check_site.api_problems(site, pages) == [
        "API reference: no entry for vsj.params.Parameters.hash"]
    assert check_site.cli_problems(site, pages) == [
        "CLI reference: no section for `vsj fit wrist`"]
