#!/usr/bin/python3
"""Test double for the sweep tests (never shipped): stands in for demfem_run
(`demfem sweep --demfem-run tests/sweep/fault_demfem_run.py`) and runs the real one
($DEMFEM_TEST_REAL_RUN), injecting faults into chosen members on their first attempt:

  DEMFEM_TEST_KILL="s00_r01=demfem_run,s01_r02=dem_server"  (a stage: "s00_r01/load=...")
      once a checkpoint after step 0 is committed, SIGKILL from outside to the member's
      demfem_run (the coupler) or to its dem_server / fem_server; the first attempt only
      (a marker file in the member folder remembers it).
  DEMFEM_TEST_FAIL="s01_r00"  with DEMFEM_TEST_FAIL_WHILE=FILE
      the member exits 1 at once, without running, on every attempt while FILE exists.
  DEMFEM_TEST_RECORD=SECONDS
      runs nothing: writes its start and end times, CUDA_VISIBLE_DEVICES and
      OMP_NUM_THREADS to <member>/pool_record.json around a sleep of SECONDS (for the pool's
      CPU and GPU accounting, which needs no solver).
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

real = os.environ["DEMFEM_TEST_REAL_RUN"]
args = sys.argv[1:]
if "--output-dir" not in args or "--check" in args:
    os.execv(real, [real] + args)
out = Path(args[args.index("--output-dir") + 1])
# A member's folder is members/<id>; a stage of a chained member writes into
# members/<id>/<stage>, named "<id>/<stage>" in the lists below.
member = out.name if out.parent.name == "members" else f"{out.parent.name}/{out.name}"
if os.environ.get("DEMFEM_TEST_RECORD"):
    import json
    start = time.time()
    time.sleep(float(os.environ["DEMFEM_TEST_RECORD"]))
    (out / "pool_record.json").write_text(json.dumps({
        "start": start, "end": time.time(), "gpus": os.environ.get("CUDA_VISIBLE_DEVICES"),
        "omp": os.environ.get("OMP_NUM_THREADS")}))
    sys.exit(0)


def listed(var):
    return dict(x.split("=", 1) if "=" in x else (x, "") for x in
                os.environ.get(var, "").split(",") if x)


if member in listed("DEMFEM_TEST_FAIL") and Path(os.environ["DEMFEM_TEST_FAIL_WHILE"]).exists():
    print(f"test double: member {member} fails (exit 1)", file=sys.stderr)
    sys.exit(1)
target = listed("DEMFEM_TEST_KILL").get(member)
marker = out / ".test_killed"
if target is None or marker.exists():
    os.execv(real, [real] + args)
marker.write_text(target + "\n")
p = subprocess.Popen([real] + args)


def children(pid):
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            comm = stat[stat.index("(") + 1:stat.rindex(")")]
            ppid = int(stat[stat.rindex(")") + 2:].split()[1])
            if ppid == pid:
                out.append((int(d.name), comm))
    return out


killed = False
# No deadline of its own: the run's end ends the wait (a busy machine only makes it longer).
while p.poll() is None:
    ready = [m for m in (out / "checkpoints").glob("step-*/manifest.json")
             if m.parent.name != "step-000000"]
    if ready:
        if target == "demfem_run":
            victim = p.pid
        else:
            victim = next((pid for pid, comm in children(p.pid) if comm == target), None)
        if victim is not None:
            os.kill(victim, signal.SIGKILL)
            print(f"test double: SIGKILL to {target} (pid {victim}) of member {member} after "
                  f"{ready[0].parent.name}", file=sys.stderr)
            killed = True
            break
    time.sleep(0.001)
if not killed:
    marker.write_text("missed\n")  # the test sees it and fails with this reason
code = p.wait()
sys.exit(128 - code if code < 0 else code)
