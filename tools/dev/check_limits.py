#!/usr/bin/python3
"""The size limits of the house (docs/architecture.md, "Limits"): no source file over 1,000
lines, and no function over 200 lines outside tests/ and bench/ (tests and benches hold long
scripted scenarios on purpose).

usage: tools/dev/check_limits.py [--root DIR] [--max-file N] [--max-function N] [--all]

What is measured:
* files: every C++, CUDA and Python file that git tracks (.cpp .cc .c .hpp .h .cu .cuh .py),
  all its lines;
* Python functions: `def` to the function's last line (ast), nested functions and classes
  inside counting towards the function that holds them;
* C/C++/CUDA functions: from the line of a function body's opening brace to the line of its
  closing brace, found by braces in the text with comments, strings and character literals
  blanked out. A brace opens a function body when it stands at namespace or class level
  (not inside another function) and what stands before it since the last ';', '{' or '}'
  holds a '(' and starts with none of namespace, class, struct, union, enum, extern, and is
  not an initialiser ('= {'). Lambdas and local classes count towards their function.

Prints one line per offender, `path:line: function NAME has N lines (limit M)` or `path: N
lines (limit M)`; exit 1 when there is one, 0 otherwise. --all prints the ten longest
functions too.
"""

import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

CPP = (".cpp", ".cc", ".c", ".hpp", ".h", ".cu", ".cuh")
SOURCES = CPP + (".py",)
FUNCTION_EXEMPT = ("tests/", "bench/")  # long scripted scenarios by design
_SCOPE_WORDS = re.compile(r"^\s*(?:template\s*<[^{]*>\s*)?(namespace|class|struct|union|enum|extern)\b")
_NAME = re.compile(r"([A-Za-z_~][A-Za-z0-9_:<>~]*(?:operator\s*[^\s(]+)?)\s*\(")


def blank_literals(text):
    """The C++ text with comments, string and character literals replaced by blanks (line
    breaks kept, so that line numbers stay), raw strings included."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c == "R" and text.startswith('R"', i) and (i == 0 or not text[i - 1].isalnum()):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = text.find(")" + m.group(1) + '"', i)
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif c in "\"'":
            # a digit separator (1'000'000) is no character literal
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum():
                out.append(" ")
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def cpp_functions(text):
    """(name, first line, line count) of every function body at namespace or class level."""
    code = blank_literals(text)
    # preprocessor lines (a #define's braces, #if branches' headers) are not code here
    code = re.sub(r"(?m)^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", lambda m: re.sub(r"[^\n]", " ", m.group(0)), code)
    found = []
    stack = []  # per open brace: "scope", "function" or "block"
    header_start = 0
    line = 1
    starts = []  # (line of the body's brace, name) per open function
    for i, c in enumerate(code):
        if c == "\n":
            line += 1
        elif c == ";":
            header_start = i + 1
        elif c == "{":
            header = code[header_start:i]
            in_function = any(k in ("function", "block") for k in stack)
            kind = "block"
            if not in_function:
                if _SCOPE_WORDS.match(header) or "(" not in header or \
                        re.search(r"=\s*$", header):
                    kind = "scope" if "(" not in header or _SCOPE_WORDS.match(header) else "block"
                else:
                    kind = "function"
            stack.append(kind)
            if kind == "function":
                names = _NAME.findall(header.split("(")[0] + "(")
                starts.append((line, names[-1] if names else "?"))
            header_start = i + 1
        elif c == "}":
            kind = stack.pop() if stack else "scope"
            if kind == "function":
                first, name = starts.pop()
                found.append((name, first, line - first + 1))
            header_start = i + 1
    return found


def python_functions(text, path):
    try:
        tree = ast.parse(text, filename=str(path))
    except SyntaxError as e:
        raise SystemExit(f"check_limits: {path}:{e.lineno}: cannot parse ({e.msg})")
    out = []

    def visit(node, inside_function):
        for child in ast.iter_child_nodes(node):
            is_fn = isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if is_fn and not inside_function:
                out.append((child.name, child.lineno, child.end_lineno - child.lineno + 1))
            visit(child, inside_function or is_fn)

    visit(tree, False)
    return out


def tracked_sources(root):
    r = subprocess.run(["git", "-C", str(root), "ls-files", "-z"], capture_output=True)
    if r.returncode != 0:
        raise SystemExit(f"check_limits: {root}: not a git checkout "
                         f"({r.stderr.decode(errors='replace').strip()})")
    names = [p for p in r.stdout.decode().split("\0") if p.endswith(SOURCES)]
    return [p for p in sorted(names) if (root / p).is_file()]


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2])
    ap.add_argument("--max-file", type=int, default=1000)
    ap.add_argument("--max-function", type=int, default=200)
    ap.add_argument("--all", action="store_true", help="also print the ten longest functions")
    a = ap.parse_args(argv)
    offenders, longest = [], []
    for rel in tracked_sources(a.root):
        text = (a.root / rel).read_text(errors="replace")
        lines = text.count("\n") + (0 if text.endswith("\n") or not text else 1)
        if lines > a.max_file:
            offenders.append(f"{rel}: {lines} lines (limit {a.max_file})")
        if rel.startswith(FUNCTION_EXEMPT):
            continue
        functions = python_functions(text, rel) if rel.endswith(".py") else cpp_functions(text)
        for name, first, count in functions:
            longest.append((count, f"{rel}:{first}: function {name}"))
            if count > a.max_function:
                offenders.append(f"{rel}:{first}: function {name} has {count} lines "
                                 f"(limit {a.max_function})")
    for o in offenders:
        print(o)
    if a.all:
        print("longest functions (outside tests/ and bench/):")
        for count, where in sorted(longest, reverse=True)[:10]:
            print(f"  {count:5d}  {where}")
    if offenders:
        print(f"check_limits: {len(offenders)} over the limits (docs/architecture.md, \"Limits\")",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
