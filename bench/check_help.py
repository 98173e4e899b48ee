#!/usr/bin/python3
"""ctest (issue 34, item 17): every benchmark in <build>/bench answers --help with its usage
and exit status 0, running nothing and writing no JSON, and refuses an unknown option
(exit status != 0) before running anything. The benchmarks are found at test time (every
executable file in the folder), so a new one is covered without a list to keep.

  check_help.py BUILD/bench
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


def main(argv):
    folder = Path(argv[1])
    benches = sorted(p for p in folder.iterdir()
                     if p.is_file() and os.access(p, os.X_OK))
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
