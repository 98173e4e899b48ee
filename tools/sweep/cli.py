"""demfem sweep FILE [options]: the command line (docs/sweeps.md)."""

import argparse
import fcntl
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from sweep import records, slurm, status
from sweep.collect import collect
from sweep.exit_status import EXIT_BAD_INPUT, EXIT_FAILED
from sweep.member import Handle, describe_exit, run_member, run_units
from sweep.plan import build_plan, check_identity, load_plan, save_plan
from sweep.pool import LocalPool, machine_cpus, machine_gpus
from sweep.progress import Reporter, eta_seconds, line
from sweep.safe_text import control_character
from sweep.sweep_file import SlurmOptions, SweepError, read_sweep_file

ROOT = Path(__file__).resolve().parents[2]


def default_demfem_run():
    build = os.environ.get("DEMFEM_BUILD_DIR") or str(ROOT / "build")
    return Path(build) / "bin" / "demfem_run"


def parser():
    p = argparse.ArgumentParser(
        prog="demfem sweep",
        description="Runs a parameter study with repetitions (a sweep file, docs/sweeps.md): "
        "locally in a process pool, or on Slurm as job arrays. Running it again skips "
        "finished members and retries the others from their checkpoints. Exit status: 0 all "
        "members done (or submitted, or status/collect done), 1 a member failed, 2 bad input, "
        "128+N stopped by signal N.")
    p.add_argument("file", metavar="FILE", help="sweep file (TOML)")
    mode = p.add_argument_group("what to do (default: run the members locally, then collect)")
    mode.add_argument("--slurm", action="store_true",
                      help="submit the members that are not done, queued or running as Slurm "
                      "job arrays (one member per array task)")
    mode.add_argument("--wait", action="store_true",
                      help="with --slurm: wait until the tasks end, showing progress, then "
                      "collect")
    mode.add_argument("--status", action="store_true",
                      help="show every member's state (local or Slurm) and the ETA")
    mode.add_argument("--collect", action="store_true",
                      help="write members.csv, summary.csv, series_*.csv and plots/ from the "
                      "done members")
    p.add_argument("--output-dir", help="the sweep's folder (default: sweep.output_dir)")
    p.add_argument("--demfem-run", help="the demfem_run executable (default: "
                   "$DEMFEM_BUILD_DIR/bin/demfem_run, else build/bin/demfem_run of this "
                   "checkout)")
    loc = p.add_argument_group("local runs")
    loc.add_argument("--jobs", type=int, default=None, metavar="N",
                     help="at most N members at once (default: execution.jobs, else as many "
                     "as the cores allow)")
    loc.add_argument("--cpus", type=int, default=None, metavar="N",
                     help="cores the members may use together (default: this process's CPUs)")
    loc.add_argument("--gpus", default=None, metavar="LIST",
                     help="GPU ids for members with dem.backend = \"cuda\", e.g. 0,1 (default: "
                     "CUDA_VISIBLE_DEVICES, else nvidia-smi's list)")
    loc.add_argument("--no-collect", action="store_true", help="do not collect at the end")
    p.add_argument("--no-plots", action="store_true",
                   help="collect the tables only (no matplotlib; faster)")
    loc.add_argument("--progress-interval", type=float, default=10.0, metavar="S",
                     help="seconds between progress lines when not on a terminal (default 10)")
    p.add_argument("--max-retries", type=int, default=None, metavar="N",
                   help="attempts after the first of a failing member (default: "
                   "execution.max_retries)")
    p.add_argument("--skip-failed", action="store_true",
                   help="do not run again members that failed in an earlier run")
    p.add_argument("--no-check", action="store_true",
                   help="do not check each setting with demfem_run --check before starting")
    sl = p.add_argument_group("Slurm (override the [slurm] table of the sweep file)")
    for name in ("partition", "time", "account", "qos", "mem"):
        sl.add_argument(f"--{name}", default=None)
    sl.add_argument("--max-concurrent", type=int, default=None, metavar="N",
                    help="at most N tasks of an array at once (sbatch --array=...%%N)")
    sl.add_argument("--sbatch-option", action="append", default=[], metavar="OPT",
                    help="another sbatch option, e.g. --sbatch-option=--constraint=a100 "
                    "(repeatable)")
    sl.add_argument("--poll", type=float, default=10.0, metavar="S",
                    help="with --wait: seconds between squeue queries (default 10)")
    p.add_argument("--member-task", nargs=2, metavar=("PLAN", "INDEX"),
                   help=argparse.SUPPRESS)  # a Slurm array task (the sbatch script)
    return p


def main(argv):
    # A Slurm array task: `python3 -m sweep --member-task PLAN INDEX` (no sweep file).
    if "--member-task" in argv:
        i = argv.index("--member-task")
        if len(argv) < i + 3:
            print("demfem sweep: --member-task PLAN INDEX", file=sys.stderr)
            return EXIT_BAD_INPUT
        return member_task(argv[i + 1], argv[i + 2])
    args = parser().parse_args(argv)
    try:
        return run(args)
    except SweepError as e:
        print(f"demfem sweep: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT


def check_positive(name, v):
    if v is not None and v < 1:
        raise SweepError(f"--{name} is {v}, must be >= 1")


def run(args):
    spec = read_sweep_file(args.file)
    check_positive("jobs", args.jobs)
    check_positive("cpus", args.cpus)
    if args.max_retries is not None and not 0 <= args.max_retries <= 100:
        raise SweepError(f"--max-retries is {args.max_retries}, accepted [0, 100]")
    if args.poll <= 0 or args.progress_interval < 0:
        raise SweepError("--poll must be > 0 and --progress-interval >= 0 (seconds)")
    if args.wait and not args.slurm:
        raise SweepError("--wait goes with --slurm (a local run always waits)")
    if args.output_dir and control_character(args.output_dir):
        raise SweepError(f"--output-dir {args.output_dir!r} "
                         f"{control_character(args.output_dir)}: not accepted in a folder name")
    out = Path(args.output_dir) if args.output_dir else spec.output_dir
    exe = Path(args.demfem_run) if args.demfem_run else default_demfem_run()
    exe = Path(os.path.abspath(exe))
    plan = build_plan(spec, out, exe, progress=lambda done, total: print(
        f"sweep {spec.name}: planned {done} of {total} members", flush=True))
    if args.max_retries is not None:
        plan.max_retries = args.max_retries
    if args.slurm:  # before anything is written: the values go into the job scripts
        args.slurm_options = slurm_options(args, spec)
        slurm.check_folder(plan)

    if args.status or args.collect:
        states = status.gather(plan)
        if args.status:
            status.report(plan, states, print)
            print_eta(plan, states)
        if args.collect:
            for path in collect(spec, plan, states, plots=not args.no_plots):
                print(f"wrote {path}")
        return 0

    if not os.access(exe, os.X_OK):
        raise SweepError(f"{exe}: no demfem_run there (build first: ./demfem build, or give "
                         "--demfem-run)")
    Path(plan.output_dir).mkdir(parents=True, exist_ok=True)
    lock = sweep_lock(plan)
    try:
        for m in plan.members:
            check_identity(plan, m)
        states = status.gather(plan)
        todo, busy = [], []
        for m, state, rec, _ in states:
            if state in ("running", "queued"):
                busy.append((m, state))
            elif state == records.DONE or (state == records.FAILED and args.skip_failed):
                continue
            else:
                todo.append(m)
        for m, state in busy:
            print(f"member {m.id}: {state} elsewhere; left alone")
        n_done = sum(1 for (_, s, _, _) in states if s == records.DONE)
        if not args.no_check:
            check_settings(plan, todo)
        save_plan(plan, Path(plan.output_dir) / "plan.json")
        settings = len({m.setting for m in plan.members})
        print(f"sweep {plan.name}: {len(plan.members)} members ({settings} setting(s) x "
              f"{len(plan.members) // settings} repetition(s)); {n_done} done before, "
              f"{len(todo)} to run; output in {plan.output_dir}")
        if args.slurm:
            return run_slurm(args, spec, plan, todo)
        return run_local(args, spec, plan, todo, states)
    finally:
        os.close(lock)


def sweep_lock(plan):
    path = Path(plan.output_dir) / "sweep.lock"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise SweepError(f"another demfem sweep is running in {plan.output_dir} (it holds "
                         f"{path}); wait for it, or stop it")
    return fd


def check_settings(plan, todo):
    """demfem_run --check of one member per setting: a bad parameter value is found before
    any member starts, with the scene reader's own message (naming the --set)."""
    seen = set()
    total = len({m.setting for m in todo})
    for m in todo:
        if m.setting in seen:
            continue
        seen.add(m.setting)
        if len(seen) % 100 == 0:  # tens of ms each: a large grid takes a while
            print(f"sweep {plan.name}: checked {len(seen)} of {total} settings", flush=True)
        earlier = []
        for unit in run_units(plan, m):
            # An override that names an earlier stage's folder (its state file) is left out:
            # that file is made when the stage before has run; the scene's own value is checked.
            cmd = [plan.demfem_run, unit.scene, "--check"]
            for o in unit.overrides:
                if not any(f + "/" in o for f in earlier):
                    cmd += ["--set", o]
            earlier.append(unit.folder)
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise SweepError(f"setting {m.setting} (member {m.id}" +
                                 (f", stage {unit.stage}" if unit.stage else "") +
                                 f") is refused by demfem_run --check (exit {r.returncode}):\n  "
                                 + (r.stderr.strip() or r.stdout.strip()).replace("\n", "\n  "))


def print_eta(plan, states):
    c = status.counts(states)
    times = [r["run_time"] for (_, s, r, _) in states if s == records.DONE and "run_time" in r]
    running = c.get("running", 0)
    queued = sum(c.get(s, 0) for s in ("queued", "new", "interrupted", "lost"))
    eta = eta_seconds(times, queued, [], max(1, running))
    print(line(plan.name, {"done": c.get("done", 0), "running": running,
                           "failed": c.get("failed", 0), "queued": queued},
               len(plan.members), eta) +
          ("" if running or not queued else " (nothing is running: run the sweep to go on)"))


def run_local(args, spec, plan, todo, states):
    cpus = args.cpus or machine_cpus()
    gpus = [g for g in args.gpus.split(",") if g] if args.gpus is not None else machine_gpus()
    jobs = args.jobs or spec.execution.jobs
    reporter = Reporter(args.progress_interval)
    pool = LocalPool(plan, cpus, gpus, jobs, reporter)
    done_before = [r["run_time"] for (_, s, r, _) in states
                   if s == records.DONE and "run_time" in r]
    if todo:
        print(f"sweep {plan.name}: pool of {cpus} core(s)" +
              (f", at most {jobs} member(s) at once" if jobs else "") +
              (f", GPUs {','.join(gpus)}" if any(m.gpu for m in todo) else ""))
        sys.stdout.flush()
        pool.run(todo, done_before)
    states = status.gather(plan)
    if pool.stop_signal is not None:
        status.report(plan, states, print)
        return 128 + pool.stop_signal
    if not args.no_collect:
        for path in collect(spec, plan, states, plots=not args.no_plots):
            print(f"wrote {path}")
    return finish_report(plan, states)


def finish_report(plan, states):
    bad = [(m, s) for (m, s, _, _) in states if s in (records.FAILED, "lost")]
    if bad:
        print(f"sweep {plan.name}: {len(bad)} member(s) failed:", file=sys.stderr)
        status.report(plan, [x for x in states if x[1] in (records.FAILED, "lost")],
                      lambda t: print(t, file=sys.stderr), header=False)
        return EXIT_FAILED
    left = [m for (m, s, _, _) in states if s != records.DONE]
    if left:
        print(f"sweep {plan.name}: {len(left)} member(s) not done yet")
    else:
        print(f"sweep {plan.name}: all {len(plan.members)} members done")
    return 0


def slurm_options(args, spec):
    s = spec.slurm
    opt = SlurmOptions(
        partition=args.partition if args.partition is not None else s.partition,
        time=args.time if args.time is not None else s.time,
        account=args.account if args.account is not None else s.account,
        qos=args.qos if args.qos is not None else s.qos,
        mem=args.mem if args.mem is not None else s.mem,
        max_concurrent=(args.max_concurrent if args.max_concurrent is not None
                        else s.max_concurrent),
        options=list(s.options) + list(args.sbatch_option))

    def source(name):
        if name == "options":
            return "[slurm] options or --sbatch-option"
        cli = getattr(args, name) is not None
        return f"--{name}" if cli else f"{spec.file}: [slurm] {name}"
    slurm.check_options(opt, source)
    return opt


def run_slurm(args, spec, plan, todo):
    opt = args.slurm_options
    if todo:
        slurm.submit(plan, todo, opt)
    else:
        print(f"sweep {plan.name}: nothing to submit")
    if not args.wait:
        print(f"follow it with: demfem sweep {args.file} --status; then --collect")
        return 0
    reporter = Reporter(0.0)
    stop = []
    old = {s: signal.signal(s, lambda sig, f: stop.append(sig))
           for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        while not stop:
            states = status.gather(plan)
            c = status.counts(states)
            times = [r["run_time"] for (_, s, r, _) in states
                     if s == records.DONE and "run_time" in r]
            eta = eta_seconds(times, c.get("queued", 0), [], max(1, c.get("running", 0)))
            reporter.show(line(plan.name, {"done": c.get("done", 0),
                                           "running": c.get("running", 0),
                                           "failed": c.get("failed", 0) + c.get("lost", 0),
                                           "queued": c.get("queued", 0)},
                               len(plan.members), eta))
            if not c.get("queued") and not c.get("running"):
                break
            end = time.monotonic() + args.poll
            while not stop and time.monotonic() < end:  # Ctrl-C answered within 0.1 s
                time.sleep(min(0.1, max(0.0, end - time.monotonic())))
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        reporter.finish()
    if stop:
        print("demfem sweep: stopped waiting; the jobs go on (scancel them to stop them)")
        return 128 + stop[0]
    states = status.gather(plan)
    for path in collect(spec, plan, states, plots=not args.no_plots):
        print(f"wrote {path}")
    return finish_report(plan, states)


def member_task(plan_path, index_text):
    """One Slurm array task: runs member INDEX of the frozen plan, retries included."""
    try:
        plan = load_plan(plan_path)
        index = int(index_text)
        if not 0 <= index < len(plan.members) or plan.members[index].index != index:
            raise SweepError(f"{plan_path}: no member {index_text}")
    except (SweepError, ValueError) as e:
        print(f"demfem sweep: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    member = plan.members[index]
    handle = Handle()

    def on_signal(sig, frame):
        # Slurm's scancel or time limit: stop demfem_run cleanly (its checkpoints stay).
        handle.interrupt(signal.SIGINT)

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, on_signal)
    # `#SBATCH --signal=B:USR2@120` (slurm.script_text): a checkpoint, then a clean stop, before
    # the time limit; SIGUSR1 a checkpoint only. demfem_run takes it at its next coupling step.
    signal.signal(signal.SIGUSR1, lambda sig, frame: handle.forward(signal.SIGUSR1, False))
    signal.signal(signal.SIGUSR2, lambda sig, frame: handle.forward(signal.SIGUSR2, True))
    where = {k: os.environ[v] for k, v in (("slurm_job", "SLURM_ARRAY_JOB_ID"),
                                           ("slurm_task", "SLURM_ARRAY_TASK_ID"))
             if v in os.environ}
    print(f"demfem sweep {plan.name}: member {member.id} on {records.hostname()}", flush=True)
    try:
        rec = run_member(plan, member, handle, log=lambda t: print(t, flush=True), where=where)
    except SweepError as e:
        print(f"demfem sweep: {e}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if rec is None:
        return 0  # another task runs it
    state = rec["state"]
    print(f"member {member.id}: {state}" + (f" in {rec['run_time']:.2f} s"
                                            if state == records.DONE else
                                            f" ({describe_exit(rec.get('exit'))})"), flush=True)
    return {records.DONE: 0, records.FAILED: EXIT_FAILED}.get(state, 128 + signal.SIGTERM)
