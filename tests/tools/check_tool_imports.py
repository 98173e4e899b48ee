#!/usr/bin/python3
"""ctest: every script in tools/ that a missing module stops says which module, which
interpreter lacked it and which to run it with (demfem_post.needs), with exit status 2, never
a bare traceback. Each script runs with --help under `python3 -S` (no site-packages: numpy,
matplotlib and ParaView's modules are all missing), so this fails on a script that imports
one of them before it can name it. The scripts are found at test time.

  check_tool_imports.py TOOLS_DIR
"""
import subprocess
import sys
from pathlib import Path


def main(argv):
    tools = Path(argv[1])
    scripts = sorted(tools.glob("*.py"))
    if not scripts:
        print(f"FAILED: no scripts in {tools}")
        return 1
    failed = 0
    for script in scripts:
        r = subprocess.run([sys.executable, "-S", str(script.resolve()), "--help"], capture_output=True,
                           text=True, timeout=60, cwd=tools)
        text = r.stdout + r.stderr
        if r.returncode == 0 and "usage" in text.lower():
            verdict = "ok (needs nothing beyond the standard library for --help)"
        elif r.returncode == 2 and " is missing in " in r.stderr and "run with " in r.stderr:
            verdict = "ok (names what it needs)"
        else:
            verdict = f"FAILED: exit {r.returncode}:\n{text[-600:]}"
            failed += 1
        print(f"{script.name}: {verdict}")
    print(f"{len(scripts)} script(s), {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
