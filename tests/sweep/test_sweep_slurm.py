#!/usr/bin/python3
"""ctest (under tests/sweep/slurm_cluster.sh, a real one-node Slurm): the beam example
(2 loads x 3 repetitions) as a Slurm job array gives the same aggregate table as the local
sweep, byte for byte. On the way: a member whose demfem_run is SIGKILLed inside its array
task is retried there from its checkpoint; a member that keeps failing is reported
(--status, exit 1); running the sweep again resubmits just that member as a new array.
Then, with a stand-in for demfem_run that only sleeps: a task cancelled with SIGTERM (as at
a time limit) records its member "interrupted", a task killed with SIGKILL leaves its
member "lost"; --status says so with what Slurm knows; running the sweep again resubmits
both. And the chained example (cases/sweeps/beam_chain_ci.toml): a task runs its member's
stages one after the other, and the aggregate equals the local sweep's.

  test_sweep_slurm.py BUILD/bin/demfem_run
"""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from sweep_testing import (FAULTS, SOURCE, check, check_nothing_left, run_sweep, same_file,
                           status, wait_for)

SCENE = SOURCE / "cases" / "beam_sweep_ci.toml"


def case_slurm(tmp, exe):
    check(os.environ.get("SLURM_CONF"), "SLURM_CONF is not set: run under slurm_cluster.sh")
    ref = tmp / "reference"
    run_sweep(ref, "--no-check", "--no-plots", demfem_run=exe)
    out = tmp / "slurm"
    flag = tmp / "fail.flag"
    flag.write_text("")
    env = {"DEMFEM_TEST_REAL_RUN": exe, "DEMFEM_TEST_KILL": "s00_r01=demfem_run",
           "DEMFEM_TEST_FAIL": "s01_r00", "DEMFEM_TEST_FAIL_WHILE": str(flag)}
    slurm_args = ("--slurm", "--wait", "--poll", "0.3", "--partition", "debug", "--time", "10")
    r = run_sweep(out, *slurm_args, demfem_run=FAULTS, env=env, expect=1)
    jobs = json.loads((out / "slurm" / "jobs.json").read_text())["jobs"]
    check(len(jobs) == 1 and jobs[0]["members"] == list(range(6)), f"jobs.json: {jobs}")
    script = Path(jobs[0]["script"]).read_text()
    for line in ("#SBATCH --cpus-per-task=1", "#SBATCH --partition=debug", "#SBATCH --time=10",
                 "--member-task"):
        check(line in script, f"the sbatch script lacks '{line}':\n{script}")
    check("--gres" not in script, "a GPU was requested for CPU members")
    check("s01_r00: failed, 3 attempt(s), last exit 1" in r.stderr, "failed member not reported")
    st = status(out, "s01_r00")
    check(st["state"] == "failed" and st["where"].get("slurm_job") == str(jobs[0]["job_id"]),
          f"s01_r00 record: {st}")
    a = status(out, "s00_r01")["attempts"]
    check(len(a) == 2 and a[0]["exit"] == 137 and a[1]["resume"] and a[1]["exit"] == 0,
          f"s00_r01 (killed in its array task): attempts {a}")
    check((out / "members" / "s00_r01" / ".test_killed").read_text().strip() != "missed",
          "the kill came too late")
    logs = sorted((out / "slurm" / "logs").glob("*.out"))
    check(len(logs) == 6, f"Slurm task logs: {logs}")
    r = run_sweep(out, "--status", demfem_run=FAULTS, env=env)
    check("5 done, 0 running, 0 queued, 1 failed" in r.stdout, "--status after the first run")
    # The fault is gone: running the sweep again submits a new array of just that member.
    flag.unlink()
    r = run_sweep(out, *slurm_args, demfem_run=FAULTS, env=env)
    jobs = json.loads((out / "slurm" / "jobs.json").read_text())["jobs"]
    check(len(jobs) == 2 and jobs[1]["members"] == [3], f"resubmission: {jobs}")
    check(f"submitted job {jobs[1]['job_id']}: array 3 " in r.stdout, "resubmission message")
    check(len(status(out, "s01_r00")["attempts"]) == 4, "s01_r00 ran once more")
    same_file(ref / "summary.csv", out / "summary.csv", "the aggregate tables (local, Slurm)")
    same_file(ref / "series_deflection.csv", out / "series_deflection.csv",
              "the aggregate series (local, Slurm)")
    # Nothing left to submit.
    r = run_sweep(out, "--slurm", demfem_run=FAULTS, env=env)
    check("nothing to submit" in r.stdout, "a finished sweep submitted again")
    check_nothing_left(out)
    chained_sweep(tmp, exe)
    cancelled_and_killed_tasks(tmp, exe)


def chained_sweep(tmp, exe):
    """The chained example (cases/sweeps/beam_chain_ci.toml): each array task runs its
    member's chain (pour, then load), one task per member; with a load stage killed inside its
    task (retried there from that stage's checkpoint) the aggregate equals the local sweep's."""
    chain = SOURCE / "cases" / "sweeps" / "beam_chain_ci.toml"
    ref = tmp / "chain_reference"
    run_sweep(ref, "--no-check", "--no-plots", demfem_run=exe, sweep_file=chain)
    out = tmp / "chain_slurm"
    env = {"DEMFEM_TEST_REAL_RUN": exe, "DEMFEM_TEST_KILL": "s01_r01/load=demfem_run"}
    run_sweep(out, "--slurm", "--wait", "--poll", "0.3", "--partition", "debug", "--no-plots",
              demfem_run=FAULTS, env=env, sweep_file=chain)
    jobs = json.loads((out / "slurm" / "jobs.json").read_text())["jobs"]
    check(len(jobs) == 1 and jobs[0]["members"] == list(range(4)), f"chain jobs.json: {jobs}")
    st = status(out, "s01_r01")
    loads = [a for a in st["attempts"] if a["stage"] == "load"]
    check(st["stages"]["pour"]["state"] == "done" and len(loads) == 2 and
          loads[0]["exit"] == 137 and loads[1]["resume"] and
          all(a.get("slurm_job") == str(jobs[0]["job_id"]) for a in st["attempts"]),
          f"s01_r01 (load stage killed in its array task): {st}")
    for name in ("summary.csv", "series_deflection.csv"):
        same_file(ref / name, out / name, f"the chained sweep's {name} (local, Slurm)")
    check_nothing_left(out)


def _ppid(proc):
    try:
        stat = (proc / "stat").read_text()
    except OSError:
        return None
    return int(stat[stat.rindex(")") + 2:].split()[1])


def cancelled_and_killed_tasks(tmp, exe):
    f = tmp / "slow.toml"
    f.write_text(f'[sweep]\nscene = "{SCENE}"\nname = "slow"\n[repetitions]\ncount = 3\n')
    out = tmp / "slow"
    env = {"DEMFEM_TEST_REAL_RUN": exe, "DEMFEM_TEST_RECORD": "120"}
    run_sweep(out, "--slurm", "--no-check", demfem_run=FAULTS, env=env, sweep_file=f)
    job = json.loads((out / "slurm" / "jobs.json").read_text())["jobs"][0]["job_id"]

    def state(m):
        p = out / "members" / m / "status.json"
        return json.loads(p.read_text()).get("state") if p.exists() else None

    wait_for(lambda: state("s00_r00") == "running" and state("s00_r01") == "running",
             "both tasks running")
    subprocess.run(["scancel", f"{job}_0"], check=True)  # SIGTERM, as at a time limit
    # A task that dies without a word (node failure, OOM killer): SIGKILL to the task's
    # process and then to the stand-in it started (Slurm's own scancel --signal=KILL sends
    # SIGTERM first).
    task = json.loads((out / "members" / "s00_r01" / "status.json").read_text())["pid"]
    child = [int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit() and
             _ppid(p) == task]
    os.kill(task, signal.SIGKILL)
    for c in child:
        os.kill(c, signal.SIGKILL)
    # What the script's `--signal=B:USR2@120` sends before the limit (the third task runs
    # once a CPU is free): the task passes it on (a demfem_run would checkpoint and exit 140;
    # the stand-in dies of it) and records the member interrupted, without another attempt.
    wait_for(lambda: state("s00_r02") == "running", "the third task running")
    subprocess.run(["scancel", "--batch", "--signal=USR2", f"{job}_2"], check=True)
    wait_for(lambda: not subprocess.run(["squeue", "-h", "-j", str(job)], capture_output=True,
                                        text=True).stdout.strip(), "the tasks to end")
    r = run_sweep(out, "--status", demfem_run=FAULTS, env=env, sweep_file=f)
    check("0 done, 0 running, 0 queued, 0 failed, 1 lost, 2 interrupted" in r.stdout,
          "--status after scancel")
    a = json.loads((out / "members" / "s00_r02" / "status.json").read_text())["attempts"]
    check(len(a) == 1 and a[0]["exit"] == 128 + signal.SIGUSR2,
          f"s00_r02 after SIGUSR2 to its task: attempts {a}")
    check("s00_r01: lost" in r.stdout and f"Slurm job {job}_1 ended without finishing" in r.stdout,
          "the killed task's member is not reported lost")
    check("s00_r00: interrupted" in r.stdout and "CANCELLED" in r.stdout,
          "the cancelled task's member is not reported interrupted (with Slurm's state)")
    env["DEMFEM_TEST_RECORD"] = "0.1"
    r = run_sweep(out, "--slurm", "--wait", "--poll", "0.3", "--no-check", demfem_run=FAULTS,
                  env=env, sweep_file=f)
    jobs = json.loads((out / "slurm" / "jobs.json").read_text())["jobs"]
    check(len(jobs) == 2 and jobs[1]["members"] == [0, 1, 2], f"resubmission: {jobs}")
    check(all(state(f"s00_r0{k}") == "done" for k in range(3)), "after resubmission")


if __name__ == "__main__":
    from sweep_testing import main
    sys.exit(main({"slurm": case_slurm}, ["", "slurm", sys.argv[1]]))
