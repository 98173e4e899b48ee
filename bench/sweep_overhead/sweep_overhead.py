#!/usr/bin/python3
"""The overhead of `demfem sweep` on top of its members' own run times.

N short members (the CI beam with a random bed, cases/beam_sweep_ci.toml: one load,
N repetitions) run through `demfem sweep` (local pool, no collection) and, as the
reference, through `xargs -P POOL` running the same demfem_run command lines (a pool with
no bookkeeping at all), interleaved, `--repeats` times each. For each sweep run:

  ideal   = (sum of the members' run times, as the sweep measured each demfem_run) / POOL
  ratio   = the sweep's wall time (python start to exit) / ideal

The issue's goal: ratio <= 1.2 for 20 short members. Prints a table, writes JSON (--json).

  sweep_overhead [--json FILE] [--members 20] [--repeats 3] [--end-time 0.01]
"""

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SOURCE = Path("@PROJECT_SOURCE_DIR@")
BINARY = Path("@PROJECT_BINARY_DIR@")
if str(SOURCE).startswith("@"):  # run from the source tree
    SOURCE = Path(__file__).resolve().parents[2]
    BINARY = SOURCE / "build"
sys.path.insert(0, str(SOURCE / "bench" / "common"))
import bench_meta  # noqa: E402 (the machine and commit beside the figures)
DEMFEM_RUN = BINARY / "bin" / "demfem_run"
SCENE = SOURCE / "cases" / "beam_sweep_ci.toml"





def sweep_file(tmp, members, end_time):
    # A scene copy with the run length of the benchmark (run.end_time may also be --set; the
    # copy keeps the sweep identical for both variants).
    text = SCENE.read_text().replace("end_time = 0.01 ", f"end_time = {end_time!r} ", 1)
    (tmp / "scene.toml").write_text(text)
    f = tmp / "overhead.toml"
    f.write_text(f'[sweep]\nscene = "scene.toml"\nname = "overhead"\n'
                 f"[repetitions]\ncount = {members}\n")
    return f


def run_sweep(tmp, f, k):
    out = tmp / f"sweep-{k}"
    env = dict(os.environ, PYTHONPATH=str(SOURCE / "tools"))
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "sweep", str(f), "--output-dir", str(out),
                        "--demfem-run", str(DEMFEM_RUN), "--no-collect", "--no-check",
                        "--progress-interval", "1000"], capture_output=True, text=True, env=env)
    wall = time.monotonic() - t0
    if r.returncode != 0:
        sys.exit(f"sweep_overhead: the sweep failed (exit {r.returncode}):\n{r.stdout}\n{r.stderr}")
    runs = []
    for st in sorted(out.glob("members/*/status.json")):
        rec = json.loads(st.read_text())
        runs.append(rec["run_time"])
    plan = json.loads((out / "plan.json").read_text())
    return wall, runs, plan


def run_xargs(tmp, plan, pool, k):
    """The same command lines through `xargs -P POOL`: a pool with no bookkeeping."""
    out = tmp / f"xargs-{k}"
    lines = []
    for m in plan["members"]:
        folder = out / m["id"]
        folder.mkdir(parents=True)
        cmd = [str(DEMFEM_RUN), plan["scene"], "--output-dir", str(folder)]
        for o in m["overrides"]:
            cmd += ["--set", o]
        lines.append(shlex.join(cmd) + f" > {shlex.quote(str(folder / 'log'))} 2>&1")
    (out / "commands").write_text("\n".join(lines) + "\n")
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    t0 = time.monotonic()
    commands = shlex.quote(str(out / "commands"))
    r = subprocess.run(f"xargs -d '\\n' -P {pool} -I CMD sh -c CMD < {commands}", shell=True,
                       env=env)
    wall = time.monotonic() - t0
    if r.returncode != 0:
        sys.exit("sweep_overhead: the xargs reference failed")
    return wall


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", default="")
    p.add_argument("--members", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--end-time", type=float, default=0.01,
                   help="run.end_time of each member, s (0.01: about 0.2-0.4 s per member)")
    a = p.parse_args(argv)
    if not DEMFEM_RUN.exists():
        sys.exit(f"sweep_overhead: {DEMFEM_RUN} not built")
    pool = len(os.sched_getaffinity(0))  # the sweep's default pool: cores / 1 thread
    rows = []
    with tempfile.TemporaryDirectory(prefix="demfem-sweep-overhead-") as tmp:
        tmp = Path(tmp)
        f = sweep_file(tmp, a.members, a.end_time)
        for k in range(a.repeats):
            wall, runs, plan = run_sweep(tmp, f, k)
            ideal = sum(runs) / pool
            xwall = run_xargs(tmp, plan, pool, k)
            rows.append({"repeat": k, "members": len(runs), "pool": pool,
                         "mean_run_s": statistics.fmean(runs), "sum_runs_s": sum(runs),
                         "ideal_s": ideal, "sweep_wall_s": wall, "ratio": wall / ideal,
                         "xargs_wall_s": xwall, "sweep_over_xargs": wall / xwall})
    cols = list(rows[0])
    ratios = [r["ratio"] for r in rows]
    info = {"scene": str(SCENE), "end_time": a.end_time, "goal": "ratio <= 1.2",
            "ratio_median": statistics.median(ratios), "ratio_best": min(ratios),
            "sweep_over_xargs_median": statistics.median(r["sweep_over_xargs"] for r in rows)}
    machine, commit = bench_meta.machine(with_gpu=True), bench_meta.commit(SOURCE)
    print(f"# sweep_overhead  ({machine}, commit {commit})")
    for k, v in info.items():
        print(f"#   {k} = {v:.4g}" if isinstance(v, float) else f"#   {k} = {v}")
    widths = [max(len(c), 10) for c in cols]
    print("  ".join(c.rjust(w) for c, w in zip(cols, widths)))
    for r in rows:
        print("  ".join((f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c])).rjust(w)
                        for c, w in zip(cols, widths)))
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps({"benchmark": "sweep_overhead", "machine": machine,
                                            "commit": commit, "info": info, "rows": rows},
                                           indent=2) + "\n")
        print(f"# wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
