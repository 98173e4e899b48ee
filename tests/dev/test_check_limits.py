#!/usr/bin/python3
"""tools/dev/check_limits.py on made-up trees: a C++ function of 201 lines (with braces in
comments, strings, a raw string, an initialiser and a lambda that must not confuse the count),
a Python function of 201 lines, a file of 1,001 lines are reported with their exact counts;
functions of 200 lines, and long ones under tests/, are not; exit 1 and 0 accordingly."""

import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
CHECK = HERE.parents[1] / "tools" / "dev" / "check_limits.py"


def cpp_function(name, body_lines):
    """A function whose body braces span exactly `body_lines` lines."""
    inner = ['  const char* s = "{ not a brace";  // } nor this',
             '  auto f = [](int x) { return x; };',
             '  const char* r = R"x({{{)x";',
             "  /* } */ int a[] = {1, 2};"]
    inner += ["  (void)0;"] * (body_lines - 2 - len(inner))
    return [f"int {name}(int v) {{"] + inner + ["}"]


def py_function(name, lines):
    return [f"def {name}(v):"] + ["    v += 1"] * (lines - 2) + ["    return v"]


def make_tree(root):
    files = {
        "src/long.cpp": ["namespace demo {", "struct S { int x{0}; };",
                         "const int table[] = {1, 2, 3};"] +
                        cpp_function("too_long", 201) + cpp_function("just_fits", 200) +
                        ["}  // namespace demo"],
        "src/long.py": py_function("too_long", 201) + py_function("just_fits", 200),
        "src/big.hpp": ["// filler"] * 1001,
        "tests/test_long.cpp": cpp_function("scenario", 400),
    }
    for rel, lines in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("\n".join(lines) + "\n")
    subprocess.run(["git", "init", "-q", str(root)], check=True)
    subprocess.run(["git", "-C", str(root), "add", "."], check=True)


def main():
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        make_tree(root)
        r = subprocess.run([sys.executable, str(CHECK), "--root", str(root)],
                           capture_output=True, text=True)
        want = {"src/big.hpp: 1001 lines (limit 1000)",
                "src/long.cpp:4: function too_long has 201 lines (limit 200)",
                "src/long.py:1: function too_long has 201 lines (limit 200)"}
        got = set(r.stdout.splitlines())
        if got != want:
            failures.append(f"offenders {sorted(got)}, expected {sorted(want)}")
        if r.returncode != 1:
            failures.append(f"exit {r.returncode} with offenders, expected 1")
        for rel in ("src/long.cpp", "src/long.py", "src/big.hpp"):
            (root / rel).unlink()
        subprocess.run(["git", "-C", str(root), "add", "-A"], check=True)
        r = subprocess.run([sys.executable, str(CHECK), "--root", str(root)],
                           capture_output=True, text=True)
        if r.returncode != 0 or r.stdout:
            failures.append(f"a tree with only a long test function: exit {r.returncode}, "
                            f"output {r.stdout!r} (tests/ is exempt)")
    for f in failures:
        print("FAIL:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
