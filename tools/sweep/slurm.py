"""Slurm: one job array per resource request (threads, GPU), one member per array task (the
task index is the member's index). A task runs the member exactly as the local pool does
(retries from its checkpoints included) and writes the same record into the member folder;
the sweep folder keeps the frozen plan each submission used and the job ids."""

import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

from sweep import records
from sweep.plan import save_plan
from sweep.safe_text import (SLURM_VALUE_RULES, sbatch_option_problem, script_path_problem,
                             slurm_value_problem)
from sweep.sweep_file import SweepError

JOBS_FILE = "jobs.json"
CHECKPOINT_BEFORE_LIMIT_S = 120  # s: SIGUSR2 (checkpoint and stop) this long before the limit
ACTIVE = {"PENDING": "queued", "CONFIGURING": "running", "RUNNING": "running",
          "COMPLETING": "running", "SUSPENDED": "running", "REQUEUED": "queued",
          "RESIZING": "running", "SIGNALING": "running", "STAGE_OUT": "running"}


def slurm_dir(plan):
    return Path(plan.output_dir) / "slurm"


def tool(name):
    path = shutil.which(name)
    if not path:
        raise SweepError(f"{name} not found on PATH: --slurm needs the Slurm client commands "
                         "(a login node of a cluster; Debian: slurm-client)")
    return path


def array_spec(indices):
    """[0, 1, 2, 5, 7, 8] -> '0-2,5,7-8'."""
    out, idx = [], sorted(indices)
    i = 0
    while i < len(idx):
        j = i
        while j + 1 < len(idx) and idx[j + 1] == idx[j] + 1:
            j += 1
        out.append(str(idx[i]) if i == j else f"{idx[i]}-{idx[j]}")
        i = j + 1
    return ",".join(out)


def load_jobs(plan):
    rec = records.read_json(slurm_dir(plan) / JOBS_FILE)
    return rec.get("jobs", []) if rec else []


def check_options(opt, source):
    """Refuses a value that the sbatch script cannot carry as it is (safe_text); `source(name)`
    names where it came from (the sweep file's key or the command line's option)."""
    for name in SLURM_VALUE_RULES:
        bad = slurm_value_problem(name, getattr(opt, name))
        if bad:
            raise SweepError(f"{source(name)}: {bad}")
    for o in opt.options:
        bad = sbatch_option_problem(o)
        if bad:
            raise SweepError(f"{source('options')}: {bad}")


def check_folder(plan):
    """The sweep folder and name go into #SBATCH lines (--chdir, --output, --job-name)."""
    bad = script_path_problem(plan.output_dir)
    if bad:
        raise SweepError(f"the sweep folder {plan.output_dir!r} {bad}; --slurm needs a folder "
                         "without them (sweep.output_dir or --output-dir)")
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", plan.name):
        raise SweepError(f"the sweep name {plan.name!r} is not letters, digits and _.-")


def script_text(plan, plan_path, threads, gpu, opt):
    """The sbatch script of one array; `opt` is a sweep_file.SlurmOptions. Every value is
    checked again here (the sweep file's reader and the command line check them first, with
    the key or option named): the #SBATCH lines are read by sbatch, the others by bash, and a
    newline in any value would be a command of its own."""
    check_options(opt, lambda name: f"[slurm] {name}")
    check_folder(plan)
    d = slurm_dir(plan)
    tools = Path(__file__).resolve().parent.parent
    lines = ["#!/bin/bash",
             f"# demfem sweep {plan.name}: one member per array task (the task id is the "
             "member's index in the plan); written by `demfem sweep --slurm` (docs/sweeps.md).",
             f"#SBATCH --job-name=demfem-{plan.name}",
             f"#SBATCH --output={d / 'logs' / '%A_%a.out'}",
             f"#SBATCH --chdir={plan.output_dir}",
             "#SBATCH --ntasks=1",
             f"#SBATCH --cpus-per-task={threads}"]
    if gpu:
        lines.append("#SBATCH --gres=gpu:1")
    for flag, value in (("partition", opt.partition), ("time", opt.time),
                        ("account", opt.account), ("qos", opt.qos), ("mem", opt.mem)):
        if value:
            lines.append(f"#SBATCH --{flag}={value}")
    for o in opt.options:
        lines.append(f"#SBATCH {o}")
    if not any(o.startswith("--signal") for o in opt.options):
        # Two minutes before the time limit the task asks its demfem_run for a checkpoint and
        # a stop (cli.member_task): the member goes on from there when the sweep runs again,
        # instead of from its last periodic checkpoint.
        lines.append(f"#SBATCH --signal=B:USR2@{CHECKPOINT_BEFORE_LIMIT_S}")
    lines += ["",
              f"export PYTHONPATH={shlex.quote(str(tools))}${{PYTHONPATH:+:$PYTHONPATH}}",
              f"exec {shlex.quote(sys.executable)} -m sweep --member-task "
              f"{shlex.quote(str(plan_path))} \"$SLURM_ARRAY_TASK_ID\"", ""]
    return "\n".join(lines)


def submit(plan, members, opt, log=print):
    """Submits `members` as job arrays (one per distinct threads/GPU request); returns the
    job records added to jobs.json."""
    sbatch = tool("sbatch")
    d = slurm_dir(plan)
    (d / "logs").mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%d-%H%M%S") + f"-{os.getpid()}"
    # Tasks read the plan as it was at submission, whatever happens to the sweep file later.
    plan_path = d / f"plan-{stamp}.json"
    save_plan(plan, plan_path)
    groups = {}
    for m in members:
        groups.setdefault((m.threads, m.gpu), []).append(m.index)
    jobs = load_jobs(plan)
    added = []
    for n, ((threads, gpu), indices) in enumerate(sorted(groups.items())):
        script = d / f"array-{stamp}-{n}.sh"
        script.write_text(script_text(plan, plan_path, threads, gpu, opt))
        spec = array_spec(indices)
        if opt.max_concurrent > 0:
            spec += f"%{opt.max_concurrent}"
        cmd = [sbatch, "--parsable", f"--array={spec}", str(script)]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise SweepError(f"sbatch failed (exit {r.returncode}): {r.stderr.strip()}\n"
                             f"  command: {shlex.join(cmd)}")
        job_id = r.stdout.strip().split(";")[0]
        if not job_id.isdigit():
            raise SweepError(f"sbatch printed no job id: {r.stdout.strip()!r}")
        rec = {"job_id": int(job_id), "members": indices, "script": str(script),
               "plan": str(plan_path), "threads": threads, "gpu": gpu,
               "submitted": records.now()}
        jobs.append(rec)
        added.append(rec)
        records.write_json_atomic(d / JOBS_FILE, {"jobs": jobs})
        log(f"submitted job {job_id}: array {spec} ({len(indices)} member(s), "
            f"{threads} CPU(s){', 1 GPU' if gpu else ''} each); script {script}")
    return added


def active_tasks(job_ids):
    """{(array job id, task index): 'queued' | 'running'} for our jobs still known to squeue.
    Raises SweepError when squeue itself fails (Slurm not reachable)."""
    if not job_ids:
        return {}
    squeue = tool("squeue")
    r = subprocess.run([squeue, "-h", "-r", "-u", str(os.getuid()), "-o", "%F|%K|%T"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SweepError(f"squeue failed (exit {r.returncode}): {r.stderr.strip()}")
    wanted = {int(j) for j in job_ids}
    out = {}
    for row in r.stdout.splitlines():
        parts = row.strip().split("|")
        if len(parts) != 3 or not parts[0].isdigit() or not parts[1].isdigit():
            continue
        if int(parts[0]) in wanted:
            out[(int(parts[0]), int(parts[1]))] = ACTIVE.get(parts[2], "running")
    return out


def ended_tasks(job_ids):
    """{(array job id, task index): 'STATE exit N:M'} for ended tasks, from sacct where
    accounting is enabled, else from scontrol (which remembers jobs for MinJobAge); {} when
    neither knows."""
    out = {}
    if not job_ids:
        return out
    sacct = shutil.which("sacct")
    if sacct:
        r = subprocess.run([sacct, "-n", "-P", "-X", "-j", ",".join(str(j) for j in job_ids),
                            "-o", "JobID,State,ExitCode"], capture_output=True, text=True)
        if r.returncode == 0:
            for row in r.stdout.splitlines():
                m = re.fullmatch(r"(\d+)_(\d+)\|([^|]*)\|([^|]*)", row.strip())
                if m:
                    out[(int(m.group(1)), int(m.group(2)))] = f"{m.group(3)} exit {m.group(4)}"
            if out:
                return out
    scontrol = shutil.which("scontrol")
    if scontrol:
        for j in job_ids:
            r = subprocess.run([scontrol, "-o", "show", "job", str(j)], capture_output=True,
                               text=True)
            if r.returncode != 0:
                continue
            for row in r.stdout.splitlines():
                f = dict(re.findall(r"(\w+)=(\S*)", row))
                if f.get("ArrayJobId", "").isdigit() and f.get("ArrayTaskId", "").isdigit():
                    out[(int(f["ArrayJobId"]), int(f["ArrayTaskId"]))] = \
                        f"{f.get('JobState', '?')} exit {f.get('ExitCode', '?')}"
    return out


def last_job_of(jobs):
    """{member index: job record} of the latest submission of each member."""
    latest = {}
    for j in jobs:
        for i in j["members"]:
            latest[i] = j
    return latest
