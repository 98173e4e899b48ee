#!/usr/bin/python3
"""ctest: every benchmark in <build>/bench answers --help with its usage and a one-line
description (what `./demfem bench list` shows) and exit status 0, running nothing and
writing no JSON, and refuses an unknown option (exit status != 0) before running anything.
The benchmarks are found at test time (every executable file in the folder), so a new one is
covered without a list to keep.

  check_help.py BUILD/bench           the check
  check_help.py --list BUILD/bench    each benchmark's name and description (bench list)
"""

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

# A benchmark that ignores --help runs instead: seconds to minutes. This bounds that case;
# it is not a speed requirement (an answer to --help takes milliseconds).
HANG_GUARD_S = 120


def run(exe, args, cwd):
    """The finished process, or None when it ran past the guard (then it and whatever it
    started are stopped: SIGTERM to its process group, SIGKILL 10 s later)."""
    p = subprocess.Popen([str(exe)] + args, cwd=cwd, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL,
                         start_new_session=True)
    try:
        out, err = p.communicate(timeout=HANG_GUARD_S)
        return subprocess.CompletedProcess(p.args, p.returncode, out, err)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGTERM)
        try:
            p.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.communicate()
        return None


# A description longer than this does not fit `bench list`'s line.
DESCRIPTION_MAX = 140


def description(help_text):
    """The one-line description in a --help text: its first line outside the usage block (a
    line opening with "usage:" and the indented or blank lines after it), as CLI11 prints it
    first and argparse after the usage."""
    lines = help_text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.lower().startswith("usage:"):
            i += 1
            while i < len(lines) and (not lines[i].strip() or lines[i][0].isspace()):
                i += 1
            continue
        if line.strip():
            return line.strip()
        i += 1
    return ""


def check(exe):
    """Problems of one benchmark: [] when it behaves."""
    problems = []
    with tempfile.TemporaryDirectory(prefix="demfem-bench-help-") as tmp:
        json = Path(tmp) / "out.json"
        r = run(exe, ["--help", "--json", str(json)], tmp)
        if r is None:
            problems.append(f"--help did not end within {HANG_GUARD_S} s: it runs the benchmark")
        else:
            if r.returncode != 0:
                problems.append(f"--help exited {r.returncode}: {r.stderr.strip()[-300:]}")
            if "--json" not in r.stdout:
                problems.append(f"--help printed no usage naming its options:\n{r.stdout[-300:]}")
            text = description(r.stdout)
            if not text or text.startswith("-") or len(text) > DESCRIPTION_MAX:
                problems.append(f"--help opens with no one-line description (at most "
                                f"{DESCRIPTION_MAX} characters, before or after the usage): "
                                f"{text!r}")
        left = sorted(p.name for p in Path(tmp).iterdir())
        if left:
            problems.append(f"--help wrote {left} (it ran)")
        r = run(exe, ["--no-such-option", "--json", str(json)], tmp)
        if r is None:
            problems.append("--no-such-option ran the benchmark")
        elif r.returncode == 0:
            problems.append("--no-such-option was accepted (exit 0)")
        elif json.exists():
            problems.append("--no-such-option wrote the JSON (it ran)")
    return problems


def list_benches(benches):
    """`./demfem bench list`: each benchmark's name and the description its --help gives."""
    width = max(len(exe.name) for exe in benches)
    for exe in benches:
        with tempfile.TemporaryDirectory(prefix="demfem-bench-list-") as tmp:
            r = run(exe, ["--help"], tmp)
        text = description(r.stdout) if r is not None and r.returncode == 0 else ""
        print(f"  {exe.name:<{width}}  {text or '(no description: its --help fails)'}")
    return 0


def main(argv):
    listing = len(argv) > 1 and argv[1] == "--list"
    if listing:
        argv = argv[1:]
    folder = Path(argv[1]).resolve()
    benches = sorted(p for p in folder.iterdir()
                     if p.is_file() and os.access(p, os.X_OK))
    if listing:
        return list_benches(benches) if benches else 1
    if not benches:
        print(f"FAILED: no benchmark executables in {folder}")
        return 1
    failed = 0
    for exe in benches:
        problems = check(exe)
        print(f"{exe.name}: " + ("ok" if not problems else "; ".join(problems)))
        failed += bool(problems)
    print(f"{len(benches)} benchmark(s), {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
