"""Checking a Markdown document (README.md) against the code: its commands, flags,
snippets, names, files and figures. tests/test_readme.py says what is checked and
applies it; each ``*_problems`` function returns what is wrong, one message a finding,
each naming the document's line."""

from __future__ import annotations

import argparse
import ast
import contextlib
import dataclasses
import glob
import importlib
import inspect
import io
import pkgutil
import re
import shlex
import subprocess
import traceback
from dataclasses import dataclass
from pathlib import Path

import vsj
from doc_examples import check_toml
from vsj.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]

#: Subcommands that are only parsed, not run (the reason, and the test that runs them),
#: unless the document's command shows every flag listed beside them, which makes the
#: run cheap.
COSTLY = {
    "reproduce": (("--reduced", "--only"), "every figure of the report, half a minute; "
                                            "tests/test_reproduce.py runs it reduced"),
    "datasheet": ((), "a characterisation at many pivot positions; tests/test_datasheet.py"),
    "fmu": ((), "compiles a shared library with the C compiler; tests/test_fmu.py"),
    "fit wrist": ((), "an identification from many simulations; "
                      "tests/test_identify_wrist.py"),
    "sweep": ((), "many simulations; tests/test_sweep.py"),
    "design": ((), "an optimisation over many designs; tests/test_design.py"),
    "study": (("--quick",), "a study of many closed-loop runs or an optimisation, minutes; "
                            "tests/test_tradeoff.py and tests/test_studies.py run them"),
    "explore": ((), "serves until interrupted; make explore-browser drives it in Chromium "
                    "(tests/browser_explorer.py)"),
}
#: Options whose value is a file or directory a command writes (everything else that
#: looks like a path is an input it reads).
OUTPUT_OPTIONS = {"--out", "--write-params", "--cross-check"}
#: File name endings that make a command's argument a path.
PATH_SUFFIXES = {".csv", ".toml", ".json", ".npz", ".nc", ".fmu", ".txt", ".zarr", ".png"}
SHELL = ("", "sh", "bash", "shell", "console")


# -- reading Markdown ------------------------------------------------------------------------

@dataclass(frozen=True)
class Block:
    """A code block: its language (``""`` when not given), text, first line and the
    ``#``/``##`` section it is in."""

    lang: str
    text: str
    line: int
    section: str


@dataclass(frozen=True)
class Span:
    """An inline code span of the prose (line breaks made spaces)."""

    text: str
    line: int
    section: str


def read_markdown(text: str) -> tuple[list[Block], list[Span]]:
    """Code blocks (fenced, and indented by four spaces after a blank line) and the
    prose's code spans."""
    lines = text.splitlines()
    blocks: list[Block] = []
    prose: list[str] = []
    sections: list[str] = []
    section, fence, start, body, blank_before = "", None, 0, [], True
    indented: list[str] = []  # an indented block being read; it began at line `start`

    def close_indented() -> None:
        while indented and not indented[-1].strip():
            indented.pop()
        if indented:
            blocks.append(Block("", "\n".join(indented), start, section))
            indented.clear()

    for number, line in enumerate(lines, 1):
        sections.append(section)
        if fence is not None:
            if line.strip().startswith(fence[0]):
                blocks.append(Block(fence[1], "\n".join(body), start, section))
                fence = None
            else:
                body.append(line)
            prose.append("")
            continue
        opening = re.match(r"\s{0,3}(```+|~~~+)\s*([\w+-]*)", line)
        if opening:
            close_indented()
            fence, start, body = (opening.group(1), opening.group(2).lower()), number + 1, []
            prose.append("")
            continue
        if line.startswith("    ") and line.strip() and (indented or blank_before):
            start = start if indented else number
            indented.append(line[4:])
            prose.append("")
            continue
        if indented and not line.strip():
            indented.append("")
            prose.append("")
            continue
        close_indented()
        heading = re.match(r"(#{1,6})\s+(.*)", line)
        if heading and len(heading.group(1)) <= 2:
            section = heading.group(2).strip()
        blank_before = not line.strip()
        prose.append("" if heading else line)
    close_indented()
    joined = "\n".join(prose)
    spans = []
    # a span: matching runs of backticks within one paragraph
    for m in re.finditer(r"(?<!`)(`+)(?!`)((?:(?!\n\s*\n).)+?)(?<!`)\1(?!`)", joined, re.S):
        line = joined.count("\n", 0, m.start()) + 1
        spans.append(Span(" ".join(m.group(2).split()), line, sections[line - 1]))
    return blocks, spans


@dataclass(frozen=True)
class Command:
    """A ``vsj`` or ``make`` command: its words (synopsis brackets removed), its line,
    and whether it is complete (no brackets, no placeholders: it can be run)."""

    words: list[str]
    line: int
    complete: bool

    def __str__(self) -> str:
        return " ".join(self.words)


def is_placeholder(word: str) -> bool:
    """``FILE``, ``DIR``, ``SPEC.toml``, ``NAME=LOW,HIGH``, ``...``: a value for the
    reader to fill in."""
    stem = re.sub(r"\.[a-z0-9]+$", "", word)
    return word.strip(".") == "" or (bool(re.search(r"[A-Z]", stem))
                                     and not re.search(r"[a-z]", stem))


def command_lines(block: Block) -> list[tuple[str, int]]:
    """Logical lines of a shell block and their line numbers: ``\\`` continuations
    joined, and an indented line after a ``vsj`` command read as its continuation (a
    synopsis wrapped by hand)."""
    out: list[tuple[str, int]] = []
    pending = False
    for offset, raw in enumerate(block.text.splitlines()):
        line = re.sub(r"^\$\s+", "", raw)
        wrapped = (out and raw[:1].isspace() and line.strip()
                   and re.match(r"(\S*/)?vsj\s", out[-1][0].lstrip()))
        if pending or wrapped:
            out[-1] = (out[-1][0] + " " + line.strip().rstrip("\\"), out[-1][1])
        else:
            out.append((line.rstrip("\\"), block.line + offset))
        pending = line.rstrip().endswith("\\")
    return out


def split_command(text: str, line: int) -> Command | None:
    """A ``vsj`` or ``make`` command (environment assignments in front dropped), or
    None for any other program."""
    try:
        words = shlex.split(text, comments=True)
    except ValueError:
        return None
    while words and re.fullmatch(r"[A-Z_][A-Z0-9_]*=\S*", words[0]):
        words = words[1:]
    if not words or not (words[0] == "make" or re.fullmatch(r"(\S*/)?vsj", words[0])):
        return None
    complete = not any("[" in w or "]" in w or "|" in w or is_placeholder(w)
                       for w in words[1:])
    words = [w.strip("[]") for w in words]
    return Command([w for w in words if w], line, complete)


# -- the real parser -------------------------------------------------------------------------

def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def resolve(parser, words: list[str]):
    """Walk the subcommands named at the front of ``words``: ``(parser, path, the words
    after the path, problem or None)``."""
    path, rest = [], list(words)
    while rest and not rest[0].startswith("-"):
        subs = _subcommands(parser)
        if not subs or is_placeholder(rest[0]):
            break
        if rest[0] not in subs:
            return parser, path, rest, (f"`vsj {' '.join(path + [rest[0]])}`: no such "
                                        f"command (`vsj {' '.join(path)}` has "
                                        f"{', '.join(subs)})")
        parser = subs[rest.pop(0)]
        path.append(parser.prog.split()[-1])
    return parser, path, rest, None


def _option_like(word: str) -> bool:
    return word.startswith("-") and not re.fullmatch(r"-\.?\d.*", word)


def options_of(parser, words: list[str]) -> list[tuple[str, argparse.Action | None, list[str]]]:
    """``(flag, action, values)`` for each option in ``words``, as the parser would take
    them (action None for a flag it does not know)."""
    found, i = [], 0
    while i < len(words):
        word = words[i]
        i += 1
        if not _option_like(word):
            continue
        flag, eq, attached = word.partition("=")
        action = parser._option_string_actions.get(flag)
        values = [attached] if eq else []
        if action is not None and not eq:
            nargs = action.nargs
            if nargs is None or isinstance(nargs, int):
                count = 1 if nargs is None else nargs
                values, i = words[i:i + count], i + count
            elif nargs in ("+", "*"):
                while i < len(words) and not _option_like(words[i]):
                    values.append(words[i])
                    i += 1
            elif nargs == "?" and i < len(words) and not _option_like(words[i]):
                values, i = [words[i]], i + 1
        found.append((flag, action, values))
    return found


def value_problems(flag: str, action: argparse.Action, values: list[str]) -> list[str]:
    """What is wrong with ``values`` given to ``flag`` (placeholders are not checked;
    each of ``a|b`` is)."""
    if action.nargs == 0 and values:
        return [f"{flag} takes no value, got {values[0]!r}"]
    problems = []
    for value in values:
        for alternative in value.split("|"):
            if is_placeholder(alternative):
                continue
            if action.choices is not None and alternative not in action.choices:
                problems.append(f"{flag} {alternative}: allowed {', '.join(action.choices)}")
            elif callable(action.type):
                try:
                    action.type(alternative)
                except (TypeError, ValueError) as exc:
                    problems.append(f"{flag} {alternative}: {exc}")
    return problems


def flag_problems(parser, path: list[str], words: list[str]) -> list[str]:
    """Flags of ``words`` that the (sub)command does not have, or values it refuses."""
    problems = []
    for flag, action, values in options_of(parser, words):
        if action is None:
            known = sorted(s for s in parser._option_string_actions if s.startswith("--"))
            problems.append(f"`{' '.join(['vsj', *path])}` has no option {flag} (it has "
                            f"{', '.join(known)})")
        else:
            problems += value_problems(flag, action, values)
    return problems


def parse_problem(parser, argv: list[str]) -> str | None:
    """The real parser's complaint about a whole command line, or None."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            parser.parse_args(argv)
    except SystemExit:
        return err.getvalue().strip().splitlines()[-1]
    return None


def make_targets() -> set[str]:
    text = (ROOT / "Makefile").read_text()
    return {target for m in re.finditer(r"^([^\s#:=][^:=\n]*?)\s*:(?!=)", text, re.M)
            for target in m.group(1).split()}


def command_paths(parser, path=()) -> list[list[str]]:
    """Every (sub)command of the parser, as a path of names."""
    subs = _subcommands(parser)
    if not subs:
        return [list(path)]
    return [p for name, sub in subs.items() for p in command_paths(sub, (*path, name))]


def parser_at(parser, path: list[str]):
    """The (sub)parser of ``path`` under ``parser``."""
    for name in path:
        parser = _subcommands(parser)[name]
    return parser


# -- running code blocks ------------------------------------------------------------------

def inputs_of(words: list[str]) -> list[tuple[int, str]]:
    """(index in ``words``, word) of each path the command reads: a word that looks like
    a path and is not the value of one of `OUTPUT_OPTIONS`."""
    paths = []
    for index, word in enumerate(words):
        if word.partition("=")[0] in OUTPUT_OPTIONS or (index and words[index - 1]
                                                        in OUTPUT_OPTIONS):
            continue
        value = word.partition("=")[2] if _option_like(word) else word
        if value and ("/" in value or "*" in value or Path(value).suffix in PATH_SUFFIXES):
            paths.append((index, word))
    return paths


def prepare_argv(words: list[str], cwd: Path) -> list[str] | str:
    """The argv to run in ``cwd`` (globs expanded there, an input that only the
    repository holds given from it), or why the command can only be parsed."""
    argv = list(words)
    expanded: dict[int, list[str]] = {}
    for index, word in inputs_of(words):
        prefix, eq, path = word.partition("=") if _option_like(word) else ("", "", word)
        prefix += eq
        if any(c in path for c in "*?"):
            matches = sorted(glob.glob(path, root_dir=cwd))
            if not matches:
                return f"no file matches {path}"
            expanded[index] = [prefix + m for m in matches]
        elif not (cwd / path).exists():
            if not (ROOT / path).exists():
                return f"its input {path} is the reader's own"
            argv[index] = prefix + str(ROOT / path)
    for index in sorted(expanded, reverse=True):
        argv[index:index + 1] = expanded[index]
    return argv


def run_command(command: Command, cwd: Path, parser, origin: str) -> tuple[str, list[str]]:
    """Check one ``vsj`` command and run it where that is cheap: (``ran``, ``parsed``
    or why it was only parsed; problems)."""
    where = f"{origin}:{command.line} `{command}`"
    sub, path, rest, problem = resolve(parser, command.words[1:])
    if problem:
        return "parsed", [f"{where}: {problem}"]
    problems = [f"{where}: {p}" for p in flag_problems(sub, path, rest)]
    if problems or not command.complete:
        return "parsed", problems
    problem = parse_problem(parser, command.words[1:])
    if problem:
        return "parsed", [f"{where}: {problem}"]
    flags, reason = COSTLY.get(" ".join(path), ((), None))
    if reason is not None and not (flags and all(f in command.words for f in flags)):
        return f"parsed only ({reason})", []
    argv = prepare_argv(command.words[1:], cwd)
    if isinstance(argv, str):
        return f"parsed only ({argv})", []
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    if code != 0:
        tail = "\n    ".join((err.getvalue() or out.getvalue()).strip().splitlines()[-6:])
        return "ran", [f"{where}: exit code {code}\n    {tail}"]
    return "ran", []


def code_block_problems(text: str, cwd: Path, origin: str = "README.md"
                        ) -> tuple[list[str], list[str]]:
    """Run the document's code blocks in order in ``cwd`` (the current directory must be
    ``cwd``): commands checked and run or parsed, Python executed, TOML loaded.
    Returns (problems, one line per ``vsj`` command saying what was done with it)."""
    blocks, _ = read_markdown(text)
    parser = build_parser()
    targets = make_targets()
    problems, log = [], []
    for block in blocks:
        where = f"{origin}:{block.line}"
        if block.lang in ("python", "py"):
            try:
                exec(compile(block.text, where, "exec"), {"__name__": "__doc_example__"})
            except Exception:  # noqa: BLE001 - whatever the snippet raises is the finding
                problems.append(f"{where}: the Python block fails:\n"
                                + traceback.format_exc(limit=-3))
        elif block.lang == "toml":
            try:
                check_toml(block.text, where, cwd)
            except Exception as exc:  # noqa: BLE001 - as above
                problems.append(f"{where}: the TOML block: {type(exc).__name__}: {exc}")
        elif block.lang in SHELL:
            for line_text, line in command_lines(block):
                command = split_command(line_text, line)
                if command is None:
                    continue
                if command.words[0] == "make":
                    problems += [f"{origin}:{line}: no make target {t!r}"
                                 for t in command.words[1:]
                                 if not t.startswith("-") and t not in targets]
                    continue
                how, found = run_command(command, cwd, parser, origin)
                log.append(f"{origin}:{line}: {how}: {command}")
                problems += found
    return problems, log


# -- the prose ---------------------------------------------------------------------------------

def section_commands(parser, blocks: list[Block], spans: list[Span]
                     ) -> dict[str, list[list[str]]]:
    """Per section, the (sub)command paths its code blocks and spans name."""
    named: dict[str, list[list[str]]] = {}
    texts = [(t, line, b.section) for b in blocks if b.lang in SHELL
             for t, line in command_lines(b)]
    texts += [(s.text, s.line, s.section) for s in spans]
    for text, line, section in texts:
        command = split_command(text, line)
        if command is None or command.words[0] == "make":
            continue
        _, path, _, problem = resolve(parser, command.words[1:])
        if problem is None and path:
            named.setdefault(section, []).append(path)
    return named


def prose_problems(text: str, origin: str = "README.md") -> list[str]:
    """``vsj ...`` and ``make ...`` spans name real commands, flags and targets; a
    ``--flag value`` span names a flag of a command its section shows (of any command
    where the section shows none), with a value it accepts."""
    blocks, spans = read_markdown(text)
    parser = build_parser()
    named = section_commands(parser, blocks, spans)
    everything = command_paths(parser)
    targets = make_targets()
    problems = []
    for span in spans:
        where = f"{origin}:{span.line} `{span.text}`"
        command = split_command(span.text, span.line)
        if command is not None and command.words[0] == "make":
            problems += [f"{where}: no make target {t!r}" for t in command.words[1:]
                         if t not in targets]
        elif command is not None:
            sub, path, rest, problem = resolve(parser, command.words[1:])
            problems += [f"{where}: {p}" for p in ([problem] if problem else
                                                   flag_problems(sub, path, rest))]
        elif re.match(r"--[a-z]", span.text):
            try:
                words = [w.strip("[]") for w in shlex.split(span.text)]
            except ValueError:
                continue
            candidates = named.get(span.section) or everything
            verdicts = []
            for path in candidates:
                found = options_of(parser_at(parser, path), words)
                if found and found[0][1] is not None:
                    verdicts.append(value_problems(*found[0]))
            if not verdicts:
                shown = sorted({" ".join(p) for p in candidates})
                problems.append(f"{where}: no such option of the commands this section "
                                f"shows ({', '.join(shown)})")
            elif all(verdicts):
                problems.append(f"{where}: {verdicts[0][0]}")
    return problems


# -- names, files, figures ---------------------------------------------------------------

def tracked_files() -> list[str]:
    done = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                          check=True)
    return done.stdout.split()


def vsj_modules() -> list[object]:
    """vsj and every module in it (where a ``Class`` that a span names may live)."""
    modules = [vsj]
    for info in pkgutil.walk_packages(vsj.__path__, "vsj."):
        if not info.name.endswith("__main__"):
            modules.append(importlib.import_module(info.name))
    return modules


def _has(obj, name: str) -> bool:
    """``obj`` has the attribute, or (a class) declares it as a field or sets it on its
    instances."""
    if hasattr(obj, name):
        return True
    if not inspect.isclass(obj):
        return False
    if dataclasses.is_dataclass(obj) and name in {f.name for f in dataclasses.fields(obj)}:
        return True
    if any(name in getattr(k, "__annotations__", {}) for k in obj.__mro__):
        return True
    try:
        return f"self.{name} =" in inspect.getsource(obj)
    except (OSError, TypeError):
        return False


def _follow(obj, attributes: list[str]) -> tuple[object, str | None]:
    """The object at the end of ``attributes``, or the problem on the way."""
    for i, name in enumerate(attributes):
        if not _has(obj, name):
            return None, f"{'.'.join(attributes[:i]) or obj.__name__} has no {name!r}"
        if not hasattr(obj, name):  # a field of instances: nothing further to follow
            return None, None
        obj = getattr(obj, name)
    return obj, None


def _keywords_problem(obj, call: ast.Call) -> str | None:
    keywords = [k.arg for k in call.keywords if k.arg]
    if obj is None or not keywords or not callable(obj):
        return None
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_KEYWORD for p in signature.parameters.values()):
        return None
    missing = [k for k in keywords if k not in signature.parameters]
    return f"takes no keyword {', '.join(missing)}" if missing else None


def name_problem(text: str, modules: list[object]) -> str | None:
    """What is wrong with a ``vsj.x.y`` span, or a ``Class.attr`` / ``Class(...,
    kw=...)`` span of a class that vsj defines (None for a span that is neither)."""
    try:
        tree = ast.parse(text, mode="eval").body
    except SyntaxError:
        return None
    call = tree if isinstance(tree, ast.Call) else None
    node, chain = call.func if call else tree, []
    while isinstance(node, ast.Attribute):
        chain.insert(0, node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    if node.id == "vsj":
        # the longest importable module, then attributes
        for cut in range(len(chain), -1, -1):
            try:
                module = importlib.import_module(".".join(["vsj", *chain[:cut]]))
            except ModuleNotFoundError:
                continue
            obj, problem = _follow(module, chain[cut:])
            break
    elif node.id[:1].isupper() and (call is not None or chain):
        owners = [getattr(m, node.id) for m in modules
                  if inspect.isclass(getattr(m, node.id, None))]
        if not owners:
            return None  # not a class of vsj's (fmpy's, a placeholder)
        followed = [_follow(o, chain) for o in owners]
        good = [obj for obj, problem in followed if problem is None]
        if not good:
            return followed[0][1]
        obj, problem = good[0], None
    else:
        return None
    if problem is None and call is not None:
        problem = _keywords_problem(obj, call)
    return problem


def made_by_make(path: str) -> bool:
    """Whether ``path`` is something a make target writes: git ignores it (an output,
    never in a checkout) and the Makefile names the directory it lies in."""
    ignored = subprocess.run(["git", "check-ignore", "-q", path], cwd=ROOT).returncode == 0
    makefile = (ROOT / "Makefile").read_text()
    parts = Path(path).parts
    return ignored and any("/".join(parts[:k]) in makefile for k in range(2, len(parts) + 1))


def name_problems(text: str, origin: str = "README.md") -> list[str]:
    """Python names, C functions, repository paths (``src/...``, ``vsj/...`` and
    ``engine/c/...`` under ``src``) and source files that the document names exist."""
    blocks, spans = read_markdown(text)
    tracked = tracked_files()
    tops = {f.split("/")[0] for f in tracked if "/" in f}
    # paths inside the package, as the architecture notes write them (engine/c/laws.c)
    inner = {f.split("/")[2] for f in tracked if f.startswith("src/vsj/") and f.count("/") > 2}
    basenames = {Path(f).name for f in tracked}
    c_sources = "\n".join((ROOT / f).read_text() for f in tracked
                          if f.endswith((".c", ".h")) and f.startswith("src/"))
    modules = vsj_modules()
    words = [(s.text, s.line) for s in spans]
    words += [(w.strip("(),;:'\""), line) for b in blocks if b.lang in SHELL
              for line_text, line in command_lines(b) for w in line_text.split()]
    problems = []
    for word, line in words:
        where = f"{origin}:{line} `{word}`"
        path = word.rstrip("/")
        first = path.split("/")[0]
        if "/" in path and " " not in path and first in tops | inner | {"vsj"}:
            full = ROOT / path if first in tops else ROOT / "src" / (
                path if first == "vsj" else "vsj/" + path)
            if not glob.glob(str(full)) and not made_by_make(path):
                problems.append(f"{where}: no such file or directory in the repository")
        elif re.fullmatch(r"[\w-]+\.(py|c|h)", word):
            if word not in basenames:
                problems.append(f"{where}: no such source file in the repository")
        elif re.fullmatch(r"vsj_[a-z0-9_]+", word):
            if not re.search(rf"\b{word}\b", c_sources):
                problems.append(f"{where}: not in the C sources")
        else:
            problem = name_problem(word, modules)
            if problem:
                problems.append(f"{where}: {problem}")
    return problems


def figure_problems(text: str, origin: str = "README.md") -> list[str]:
    """Each image the document shows exists and ``make figures`` writes it."""
    images = re.findall(r"!\[[^\]]*\]\(([^)\s]+)", text)
    recipe = subprocess.run(["make", "-n", "-B", "figures"], cwd=ROOT, capture_output=True,
                            text=True).stdout
    problems = []
    for image in images:
        if not (ROOT / image).is_file():
            problems.append(f"{origin} shows {image}, which does not exist")
        if image not in recipe:
            problems.append(f"{origin} shows {image}, which `make figures` does not write")
    return problems
