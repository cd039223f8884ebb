"""The C sources stay readable: no function of the engine (``src/vsj/engine/c/*.c``), of
the binding (``src/vsj/_core.c``) or of the FMU glue (``src/vsj/fmi/*.c``) is longer than
MAX_LINES lines.

A function is found by brace matching at file level, after comments, string and
character literals and preprocessor directives are blanked out (their braces are not
code): a top-level ``{ ... }`` block whose head ends in a parameter list and holds no
``=`` (an initialiser) is a function definition. Its length runs from the first line
of its head (the return type) to its closing brace. The parser itself is checked on a
small source with each of those traps.
"""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted((ROOT / "src" / "vsj" / "engine" / "c").glob("*.c")) + [
    ROOT / "src" / "vsj" / "_core.c"] + sorted((ROOT / "src" / "vsj" / "fmi").glob("*.c"))

#: Issue 32: the engine split by job, "no function over about 150 lines", so that each
#: reads at once.
MAX_LINES = 150

# comments, string and character literals, preprocessor directives (with their
# continuation lines); alternatives are tried at each position, so a quote inside a
# comment or a comment marker inside a string is taken as part of the outer one
_NOISE = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\\n])*\"|'(?:\\.|[^'\\\n])*'"
                    r"|^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", re.S | re.M)
# a head that ends in a name and its parameter list (one level of nested parentheses,
# as in a function-pointer parameter)
_HEAD = re.compile(r"(\w+)\s*\((?:[^()]|\([^()]*\))*\)\s*$")


def functions(text: str) -> list[tuple[str, int, int]]:
    """The function definitions of a C source: (name, first line, last line), lines
    counted from 1, the first being the head's first line. Raises ValueError where the
    braces do not balance."""
    code = _NOISE.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    found, depth, head_start, brace = [], 0, 0, 0
    for i, ch in enumerate(code):
        if ch == "{":
            if depth == 0:
                brace = i
            depth += 1
        elif ch == "}":
            depth -= 1
            if depth < 0:
                raise ValueError(f"line {code.count(chr(10), 0, i) + 1}: unmatched '}}'")
            if depth == 0:
                head = code[head_start:brace]
                match = _HEAD.search(head)
                if match and "=" not in head:
                    start = head_start + len(head) - len(head.lstrip())
                    found.append((match.group(1), code.count("\n", 0, start) + 1,
                                  code.count("\n", 0, i) + 1))
                head_start = i + 1
        elif ch == ";" and depth == 0:
            head_start = i + 1
    if depth != 0:
        raise ValueError(f"{depth} '{{' left open at the end")
    return found


def test_the_parser_finds_functions_and_only_functions():
    body = "\n".join(f"    x += {k};" for k in range(MAX_LINES))
    source = f"""#include <stdio.h>
#define WRAP(x) {{ x; }}
#define BLOCK(x) \\
    {{ x; }}
typedef struct pair {{ int a, b; }} pair;
static const char *brace = "{{ in a string";
static const pair origin = {{0, 0}};
/* a comment with {{ */
static int short_one(int x) {{ // and {{ here
    if (x == '{{') {{
        return 1;
    }}
    return 0;
}}

int long_one(void (*f)(int))
{{
    int x = 0;
{body}
    f(x);
    return x;
}}
"""
    assert functions(source) == [("short_one", 9, 14), ("long_one", 16, 21 + MAX_LINES)]
    with pytest.raises(ValueError, match="left open"):
        functions("int f(void) { if (1) { return 0; }")
    with pytest.raises(ValueError, match="unmatched"):
        functions("int f(void) { return 0; } }")


def test_no_function_of_the_engine_binding_or_fmu_glue_is_longer_than_the_limit():
    offenders = []
    for path in SOURCES:
        found = functions(path.read_text())
        assert found, f"{path.relative_to(ROOT)}: no function found (parser or path broken)"
        offenders += [f"{path.relative_to(ROOT)}:{first} {name} ({last - first + 1} lines)"
                      for name, first, last in found if last - first + 1 > MAX_LINES]
    assert not offenders, (f"functions longer than {MAX_LINES} lines (split them):\n  "
                           + "\n  ".join(offenders))


def setup_warnings() -> list[str]:
    """The warning flags setup.py gives the compiler (its ``WARNINGS`` list, read from
    its text: running setup.py would build the extension)."""
    found = re.search(r"^WARNINGS = \[([^\]]*)\]", (ROOT / "setup.py").read_text(), re.M)
    assert found, "setup.py: no WARNINGS = [...] line"
    return re.findall(r'"([^"]+)"', found.group(1))


def test_the_binding_builds_without_a_warning(tmp_path):
    """The binding (``_core.c``, the one file no other test compiles) as setup.py builds
    it: the compiler and flags of Python's extensions (``$CC`` and ``$CFLAGS`` added, as
    setuptools adds them, so `make portable`'s configurations reach it too) and setup.py's
    warnings, made errors. The engine's files build with -Wall -Wextra -Werror -pedantic
    in test_c_api.py (`engine_objects`), and the FMU's glue in test_fmu.py."""
    import os
    import subprocess
    import sysconfig

    warnings = setup_warnings()
    assert {"-Wall", "-Wextra"} <= set(warnings)
    cc = (os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()
    flags = [*(sysconfig.get_config_var("CFLAGS") or "").split(),
             *(sysconfig.get_config_var("CCSHARED") or "").split(),
             *os.environ.get("CFLAGS", "").split()]
    core = ROOT / "src" / "vsj" / "_core.c"
    includes = ["-I", sysconfig.get_paths()["include"], "-I", str(core.parent / "engine" / "c")]
    done = subprocess.run([*cc, *flags, *warnings, "-Werror", *includes,
                           "-c", str(core), "-o", str(tmp_path / "core.o")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "core.o").stat().st_size > 0
