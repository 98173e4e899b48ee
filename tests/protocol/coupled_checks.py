"""What the ctest checks of coupled runs with an external backend share (test_python_sdk.py,
test_python_dem.py): the failed checks, a demfem_run run that must leave no shared-memory
segment and no process it started behind, the rows of a run's coupling.csv, and the main that
runs one case (CASE DEMFEM_RUN SOURCE_DIR) with DEMFEM_EXAMPLES naming the example's folder
(the test doubles import the example's backend from there)."""

import csv
import os
import re
import subprocess
import sys
import tempfile

failures = []
ENV = None  # os.environ with DEMFEM_EXAMPLES, set by main()


def check(ok, what):
    if not ok:
        failures.append(what)
    return ok


def run(demfem_run, scene, out, *extra, env=None, cwd=None, timeout=300):
    """demfem_run SCENE [--output-dir OUT] --quiet EXTRA...; every segment it names must be gone
    from /dev/shm and every process it started ended."""
    where = ["--output-dir", out] if out else []
    r = subprocess.run([demfem_run, scene, *where, "--quiet", *extra],
                       capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)
    for seg in re.findall(r"segment /(demfem-[0-9a-f]+)", r.stdout):
        check(not os.path.exists("/dev/shm/" + seg), f"segment {seg} left in /dev/shm")
    for pid in re.findall(r"\(pid ([0-9]+)\)", r.stdout):  # every process it started
        check(not os.path.exists(f"/proc/{pid}") or "zombie" in open(f"/proc/{pid}/status").read()
              .lower(), f"process {pid} left running")
    return r


def rows(out):
    with open(os.path.join(out, "coupling.csv")) as f:
        return list(csv.DictReader(f))


def main(cases, example):
    """Runs the case sys.argv[1] of `cases` in a fresh folder; `example` is the example folder
    below the source tree. Prints each failed check; 1 when any failed."""
    global ENV
    case, demfem_run, source = sys.argv[1], sys.argv[2], os.path.abspath(sys.argv[3])
    ENV = dict(os.environ, DEMFEM_EXAMPLES=os.path.join(source, example))
    with tempfile.TemporaryDirectory() as d:
        cases[case](demfem_run, source, d)
    for f in failures:
        print("FAILED:", f)
    return 1 if failures else 0
