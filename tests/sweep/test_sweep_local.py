#!/usr/bin/python3
"""ctest: `demfem sweep` run locally on the beam example (2 loads x 3 repetitions).

  test_sweep_local.py CASE BUILD/bin/demfem_run
  local   the table and the plots; statistics checked against numpy and the t table;
          running it again skips every member
  kill    SIGKILL of a member's demfem_run and of another member's dem_server mid-run: the
          first is retried from its checkpoint, the second recovers inside demfem_run; the
          aggregate equals that of the sweep without faults, byte for byte
  fail    a member that keeps failing is reported (exit 1, status failed, summary n = 2);
          run again once the fault is gone, only it runs, and the aggregate equals the
          reference
  resume  SIGINT to the sweep while members run: they stop cleanly (exit 130, nothing left);
          run again, the finished members are skipped, the others resume, and the aggregate
          equals the reference
  pool    the pool's accounting, with a stand-in for demfem_run that only records when it
          ran and with which CUDA_VISIBLE_DEVICES and OMP_NUM_THREADS: members with
          dem.backend = "cuda" get one GPU each, never shared; members of dem.threads = 2
          take two cores each
"""

import json
import math
import subprocess
import sys

from sweep_testing import (FAULTS, HANG_GUARD_S, SWEEP_FILE, check, check_nothing_left,
                           env_with, main, read_csv, run_sweep, same_file, status,
                           sweep_command, wait_for)

def t975_df2():
    # Student's t with 2 degrees of freedom has the closed-form quantile
    # t_p = (2p - 1) / sqrt(2 p (1 - p)); p = 0.975 gives 4.30265...
    p = 0.975
    return (2 * p - 1) / math.sqrt(2 * p * (1 - p))


def case_local(tmp, exe):
    out = tmp / "sweep"
    run_sweep(out, demfem_run=exe)
    head, rows = read_csv(out / "members.csv")
    check(head[:4] == ["member", "setting", "mass", "seed"], f"members.csv header {head}")
    check(len(rows) == 6 and all(r[head.index("status")] == "done" for r in rows),
          f"members.csv: {rows}")
    check([r[2] for r in rows] == ["10.0"] * 3 + ["20.0"] * 3, "masses")
    check([r[3] for r in rows] == ["1", "2", "3"] * 2, "seeds")
    # Each member ran the scene with its own overrides.
    for r in rows:
        log = (out / "members" / r[0] / "attempt-1.log").read_text()
        check(f"--set dem.insert[0].mass={r[2]} --set run.seed={r[3]}" in log,
              f"{r[0]}: overrides missing from the command line in its log")
    import numpy as np
    shead, srows = read_csv(out / "summary.csv")
    check(len(srows) == 2, f"summary.csv has {len(srows)} settings")
    for q in ("peak_deflection", "late_deflection", "final_deflection", "peak_force",
              "deflection_5ms"):
        qi = head.index(q)
        for s, srow in enumerate(srows):
            vals = np.array([float(r[qi]) for r in rows if r[1] == str(s)])
            check(len(vals) == 3 and srow[shead.index("n")] == "3", "n")
            mean, sd = float(srow[shead.index(q + "_mean")]), float(srow[shead.index(q + "_sd")])
            lo, hi = (float(srow[shead.index(q + "_ci95_low")]),
                      float(srow[shead.index(q + "_ci95_high")]))
            # Independent: numpy's mean and sample sd, the closed-form t quantile for df = 2.
            check(abs(mean - vals.mean()) <= 1e-12 * abs(vals.mean()), f"{q} mean")
            check(abs(sd - vals.std(ddof=1)) <= 1e-12 * vals.std(ddof=1), f"{q} sd")
            half = t975_df2() * vals.std(ddof=1) / math.sqrt(3)
            check(abs((hi - lo) / 2 - half) <= 1e-9 * half, f"{q} 95 % interval {lo}, {hi}")
            check(sd > 0, f"{q}: the repetitions of setting {s} are identical (seeds unused?)")
    # The heavier load bends the beam more, on average, after the impact.
    li = shead.index("late_deflection_mean")
    check(float(srows[1][li]) > 1.3 * float(srows[0][li]),
          f"late deflection {srows[1][li]} (20 kg) vs {srows[0][li]} (10 kg)")
    shead2, series = read_csv(out / "series_deflection.csv")
    check(shead2 == ["time", "s0_mean", "s0_sd", "s1_mean", "s1_sd"], f"series header {shead2}")
    check(len(series) == 100, f"series has {len(series)} rows, expected 100 coupling steps")
    for png in ("deflection", "peak_deflection", "late_deflection", "final_deflection",
                "peak_force", "deflection_5ms"):
        data = (out / "plots" / f"{png}.png").read_bytes()
        check(data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10000, f"{png}.png")
    check_nothing_left(out)
    # Again: every member is skipped, nothing runs.
    r = run_sweep(out, demfem_run=exe)
    check("6 done before, 0 to run" in r.stdout, "a second run did not skip the members")
    check(not list(out.glob("members/*/attempt-2.log")), "a member ran twice")
    # --status and --collect alone.
    r = run_sweep(out, "--status", demfem_run=exe)
    check("6 done, 0 running, 0 queued, 0 failed" in r.stdout, "--status")
    before = (out / "summary.csv").read_text()
    (out / "summary.csv").unlink()
    run_sweep(out, "--collect", demfem_run=exe)
    check((out / "summary.csv").read_text() == before, "--collect wrote another summary")


def reference(tmp, exe):
    ref = tmp / "reference"
    run_sweep(ref, "--no-check", "--no-plots", demfem_run=exe)
    return ref


def same_aggregate(a, b):
    same_file(a / "summary.csv", b / "summary.csv", "the aggregate tables")
    same_file(a / "series_deflection.csv", b / "series_deflection.csv", "the aggregate series")


def case_kill(tmp, exe):
    ref = reference(tmp, exe)
    out = tmp / "faulty"
    env = {"DEMFEM_TEST_REAL_RUN": exe,
           "DEMFEM_TEST_KILL": "s00_r01=demfem_run,s01_r02=dem_server"}
    run_sweep(out, demfem_run=FAULTS, env=env)
    for m in ("s00_r01", "s01_r02"):
        marker = (out / "members" / m / ".test_killed").read_text().strip()
        check(marker != "missed", f"{m}: the run ended before the test could kill it")
    st = status(out, "s00_r01")
    a = st["attempts"]
    check(len(a) == 2 and a[0]["exit"] == 137 and a[1]["resume"] and a[1]["exit"] == 0,
          f"s00_r01 (demfem_run killed): attempts {a}")
    log2 = (out / "members" / "s00_r01" / "attempt-2.log").read_text()
    check("--resume" in log2.splitlines()[0] and "resumed from checkpoint" in log2,
          "s00_r01's retry did not resume from its checkpoint")
    st = status(out, "s01_r02")
    check(len(st["attempts"]) == 1, f"s01_r02 (dem_server killed): {st['attempts']}")
    log = (out / "members" / "s01_r02" / "attempt-1.log").read_text()
    check("restarting it" in log and "1 recoveries" in log,
          "s01_r02: demfem_run did not recover its dem_server")
    same_aggregate(ref, out)
    check_nothing_left(out)


def case_fail(tmp, exe):
    ref = reference(tmp, exe)
    out = tmp / "failing"
    flag = tmp / "fail.flag"
    flag.write_text("")
    env = {"DEMFEM_TEST_REAL_RUN": exe, "DEMFEM_TEST_FAIL": "s01_r00",
           "DEMFEM_TEST_FAIL_WHILE": str(flag)}
    r = run_sweep(out, "--no-plots", demfem_run=FAULTS, env=env, expect=1)
    check("s01_r00: failed, 3 attempt(s), last exit 1" in r.stderr,
          "the failing member is not reported on stderr")
    st = status(out, "s01_r00")
    check(st["state"] == "failed" and len(st["attempts"]) == 3, f"s01_r00: {st}")
    head, rows = read_csv(out / "members.csv")
    check([r[head.index("status")] for r in rows].count("failed") == 1, "members.csv status")
    shead, srows = read_csv(out / "summary.csv")
    check(srows[1][shead.index("n")] == "2" and srows[1][shead.index("failed")] == "1",
          f"summary of the setting with the failed member: {srows[1]}")
    # --skip-failed leaves it alone.
    r = run_sweep(out, "--skip-failed", "--no-collect", demfem_run=FAULTS, env=env, expect=1)
    check("0 to run" in r.stdout, "--skip-failed ran something")
    # The fault is gone: running the sweep again runs that member only.
    flag.unlink()
    r = run_sweep(out, "--no-plots", demfem_run=FAULTS, env=env)
    check("5 done before, 1 to run" in r.stdout, "the rerun did not run just the failed member")
    check(len(status(out, "s01_r00")["attempts"]) == 4, "attempts of s01_r00")
    same_aggregate(ref, out)


def case_resume(tmp, exe):
    ref = reference(tmp, exe)
    out = tmp / "interrupted"
    p = subprocess.Popen(sweep_command(out, demfem_run=exe), env=env_with(),
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

    def states():
        return [json.loads(f.read_text()).get("state")
                for f in out.glob("members/*/status.json")]

    # Stop it once two members are done and others run.
    wait_for(lambda: states().count("done") >= 2 and "running" in states(),
             "two members done and one running")
    p.send_signal(2)
    text, _ = p.communicate(timeout=HANG_GUARD_S)
    print(text)
    check(p.returncode == 130, f"the interrupted sweep exited {p.returncode}, expected 130")
    check("stopping" in text, "no message about stopping the members")
    s = states()
    # Members that were running are "interrupted" (or "done", when one ended just as the
    # signal came); the others were never started.
    check(s.count("done") < 6 and "failed" not in s and "running" not in s, f"states {s}")
    done_first = {f.parent.name: f.stat().st_mtime_ns
                  for f in out.glob("members/*/attempt-1.log")
                  if json.loads((f.parent / "status.json").read_text())["state"] == "done"}
    check_nothing_left(out)
    r = run_sweep(out, demfem_run=exe)
    check(f"{len(done_first)} done before, {6 - len(done_first)} to run" in r.stdout,
          "the rerun did not skip exactly the finished members")
    for m, mtime in done_first.items():
        check((out / "members" / m / "attempt-1.log").stat().st_mtime_ns == mtime and
              not (out / "members" / m / "attempt-2.log").exists(), f"{m} ran again")
    same_aggregate(ref, out)


def case_pool(tmp, exe):
    import itertools
    scene = (SWEEP_FILE.parent / "../beam_sweep_ci.toml").resolve().read_text()

    def sweep(name, scene_text, *args, extra="", sleep="0.3", expect=0):
        (tmp / f"{name}.scene.toml").write_text(scene_text)
        f = tmp / f"{name}.toml"
        f.write_text(f'[sweep]\nscene = "{name}.scene.toml"\nname = "{name}"\n'
                     "[repetitions]\ncount = 6\n" + extra)
        out = tmp / name
        r = subprocess.run([sys.executable, "-m", "sweep", str(f), "--output-dir", str(out),
                            "--demfem-run", str(FAULTS), "--no-check", "--no-collect",
                            "--progress-interval", "0", *args], capture_output=True, text=True,
                           env=env_with({"DEMFEM_TEST_REAL_RUN": exe,
                                         "DEMFEM_TEST_RECORD": sleep}))
        print(r.stdout, r.stderr)
        check(r.returncode == expect, f"{name}: exit {r.returncode}, expected {expect}")
        return [json.loads(p.read_text()) for p in sorted(out.glob("members/*/pool_record.json"))]

    def most_at_once(recs):
        return max(sum(1 for r in recs if r["start"] <= t < r["end"])
                   for t in (r["start"] for r in recs))

    gpu = sweep("gpu", scene.replace('threads = 1 ', 'backend = "cuda"\nthreads = 1 '),
                "--gpus", "3,5", "--cpus", "8")
    check(len(gpu) == 6, "gpu: members missing")
    check({r["gpus"] for r in gpu} == {"3", "5"}, f"GPUs given: {[r['gpus'] for r in gpu]}")
    for a, b in itertools.combinations(gpu, 2):
        overlap = a["start"] < b["end"] and b["start"] < a["end"]
        check(not (overlap and a["gpus"] == b["gpus"]), f"GPU {a['gpus']} shared: {a}, {b}")
    check(most_at_once(gpu) == 2, f"gpu: {most_at_once(gpu)} members at once, expected 2")
    cpu = sweep("cpu", scene.replace("threads = 1 ", "threads = 2 "), "--cpus", "4")
    check(all(r["omp"] == "2" for r in cpu), "OMP_NUM_THREADS of dem.threads = 2 members")
    check(most_at_once(cpu) == 2, f"cpu: {most_at_once(cpu)} members of 2 threads at once on 4 "
          "cores, expected 2")
    one = sweep("one", scene.replace("threads = 1 ", "threads = 2 "), "--cpus", "4", "--jobs",
                "1")
    check(most_at_once(one) == 1, "--jobs 1")
    # execution.timeout: an attempt past it is stopped (SIGTERM) and retried; then failed.
    # (Without the timeout the stand-in's 30 s sleep ends with exit 0: the records tell, no
    # clock of the test's own, which a loaded machine would stretch.)
    sweep("slow", scene, "--jobs", "6", "--cpus", "6",
          extra="[execution]\ntimeout = 0.5\nmax_retries = 1\n", sleep="30", expect=1)
    st = status(tmp / "slow", "s00_r00")
    check(st["state"] == "failed" and [a["exit"] for a in st["attempts"]] == ["timeout"] * 2 and
          "timeout" in st["reason"] and all(a["wall"] < 30 for a in st["attempts"]),
          f"timed-out member: {st}")
    r = subprocess.run([sys.executable, "-m", "sweep", str(tmp / "gpu.toml"), "--output-dir",
                        str(tmp / "nogpu"), "--demfem-run", str(FAULTS), "--no-check",
                        "--gpus", ""], capture_output=True, text=True, env=env_with())
    check(r.returncode == 2 and "no GPU was found" in r.stderr, f"no GPU: {r.stderr}")


if __name__ == "__main__":
    sys.exit(main({"local": case_local, "kill": case_kill, "fail": case_fail,
                   "resume": case_resume, "pool": case_pool}, sys.argv))
