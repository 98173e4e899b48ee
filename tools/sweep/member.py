"""Running one member: demfem_run in the member's folder, retried from its last committed
checkpoint when it fails, with the member's record written atomically after every change.
The same code runs a member in the local pool and in a Slurm array task."""

import os
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from sweep import records
from sweep.exit_status import EXIT_BAD_INPUT, EXIT_BLOW_UP, EXIT_NOT_STARTED, NAMES
from sweep.plan import check_identity, write_identity

STOP_GRACE_S = 20.0  # after SIGINT/SIGTERM, how long a member may take to stop cleanly


def has_checkpoint(run):
    """True when the run's checkpoint folder (a member's, or a stage's: a RunUnit) holds a
    committed checkpoint (a manifest); demfem_run --resume verifies it and falls back to
    older ones itself."""
    if not run.checkpoints:
        return False
    return any((Path(run.folder) / run.checkpoints).glob("step-*/manifest.json"))


@dataclass
class RunUnit:
    """One demfem_run of a member: the member itself, or one of its stages (run in the
    member's folder, writing into <member>/<stage>)."""
    stage: str          # "" for a member without stages
    scene: str
    overrides: list
    folder: str         # --output-dir; the attempt logs go here too
    checkpoints: str    # relative to `folder` ("" = none)
    cwd: str


def run_units(plan, member):
    """The runs a member is made of, in order. They start in the member's folder, or in the
    sweep's shared bed folder (plan.run_dir): where [dem.load] scene prepares its beds."""
    cwd = plan.run_dir or member.folder
    if not member.stages:
        return [RunUnit("", plan.scene, member.overrides, member.folder, member.checkpoints,
                        cwd)]
    return [RunUnit(ms["name"], ps["scene"], ms["overrides"], ms["folder"], ms["checkpoints"],
                    cwd) for ps, ms in zip(plan.stages, member.stages)]


def classify(code, resumed):
    """What to do after an attempt ended with `code`: 'done', 'retry', 'fresh' (retry
    without --resume) or 'give_up'."""
    if code == 0:
        return "done"
    if code == EXIT_BAD_INPUT:
        # After --resume: no valid checkpoint left; start over. Otherwise the scene or the
        # overrides are bad, and another attempt would only repeat the message.
        return "fresh" if resumed else "give_up"
    if code in (EXIT_BLOW_UP, EXIT_NOT_STARTED):
        return "give_up"  # deterministic: the same steps blow up again; no program to run
    return "retry"        # EXIT_FAILED, EXIT_RECOVERY_EXHAUSTED, signals, timeouts


def describe_exit(code):
    if code is None:
        return "no exit status"
    if code == "timeout":
        return "timeout"
    if code in NAMES:  # demfem's own (protocol/interface/include/demfem/interface/exit_status.hpp)
        return f"exit {code} ({NAMES[code]})"
    if isinstance(code, int) and code >= 128:
        try:
            return f"exit {code} ({signal.Signals(code - 128).name})"
        except ValueError:
            pass
    if isinstance(code, int) and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            pass
    return f"exit {code}"


class _Flag:
    """A flag that a signal handler may set: threading.Event.set() takes a lock, which a
    second signal's handler, landing inside the first, would wait for forever."""

    def __init__(self):
        self._set = False

    def set(self):
        self._set = True

    def is_set(self):
        return self._set


class Handle:
    """Lets another thread, or a signal handler, stop a member's running attempt.

    A Slurm task (cli.member_task) forwards signals from a handler that runs in the main
    thread, the thread that also starts demfem_run under the lock: a plain Lock would
    deadlock there when the signal lands while Popen runs (the task then hangs until Slurm
    kills it, issue 34 item 16). So the lock is re-entrant, and a signal that comes while the
    process is being started is kept and sent to it as soon as it exists (started())."""

    def __init__(self):
        self.proc = None
        self.stop = _Flag()
        self._lock = threading.RLock()
        self._starting = False
        self._pending = []

    def interrupt(self, sig=signal.SIGINT):
        self.forward(sig, True)

    def forward(self, sig, stop):
        """Sends `sig` to the running demfem_run: a stop (interrupt) or a checkpoint request
        (SIGUSR1, or SIGUSR2: checkpoint and stop). With `stop`, no further attempt is started
        and the member counts as interrupted."""
        if stop:
            self.stop.set()
        with self._lock:
            if self._starting:
                self._pending.append(sig)  # a handler inside start(): sent once it runs
            elif self.proc is not None and self.proc.poll() is None:
                try:
                    os.kill(self.proc.pid, sig)
                except ProcessLookupError:
                    pass

    def start(self, cmd, **kw):
        """Popen(cmd) unless a stop was asked for (returns None then); signals forwarded
        meanwhile reach the new process."""
        with self._lock:
            if self.stop.is_set():
                return None
            self._starting, self._pending = True, []
            try:
                self.proc = subprocess.Popen(cmd, **kw)
            finally:
                self._starting = False
            for sig in self._pending:
                try:
                    os.kill(self.proc.pid, sig)
                except ProcessLookupError:
                    pass
            self._pending = []
            return self.proc

    def kill(self):
        with self._lock:
            if self.proc is not None and self.proc.poll() is None:
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass


def _command(plan, unit, resume):
    cmd = [plan.demfem_run, unit.scene, "--output-dir", unit.folder]
    for o in unit.overrides:
        cmd += ["--set", o]
    if resume:
        cmd.append("--resume")
    return cmd + list(plan.args)


def _tail(path, lines=6):
    try:
        text = Path(path).read_text(errors="replace").splitlines()
    except OSError:
        return ""
    return "\n".join(text[-lines:])


def run_member(plan, member, handle=None, env=None, log=print, where=None, settled=None):
    """Runs the member until it is done, fails for good, or is stopped through `handle`: its
    one run, or its stages one after the other (a stage done in an earlier sweep is not run
    again; a stage that fails or is stopped ends the member there, and the next sweep goes on
    with it). Returns its record (state 'done', 'failed', 'interrupted'), or None when
    another process holds the member (it is running elsewhere). `settled()` is called as soon
    as the last demfem_run has ended, before the final record is written (a pool can start
    the next member meanwhile: the durable write costs tens of ms on a busy disk)."""
    handle = handle or Handle()
    settled = settled or (lambda: None)
    folder = Path(member.folder)
    folder.mkdir(parents=True, exist_ok=True)
    lock = records.MemberLock(folder)
    if not lock.acquire():
        log(f"member {member.id}: another process is running it (lock {lock.path}); skipped")
        return None
    try:
        check_identity(plan, member)
        write_identity(plan, member)
        old = records.read_json(folder / records.STATUS_FILE) or {}
        rec = {"member": member.id, "index": member.index, "attempts": old.get("attempts", []),
               "host": records.hostname(), "pid": os.getpid(), "where": where or {}}
        units = run_units(plan, member)
        if member.stages:
            rec["stages"] = {u.stage: dict((old.get("stages") or {}).get(u.stage) or
                                           {"state": "new"}) for u in units}
        for i, unit in enumerate(units):
            if unit.stage and rec["stages"][unit.stage]["state"] == records.DONE:
                continue  # done in an earlier sweep: its output is what the next one uses
            last = i == len(units) - 1
            if not _run_unit(plan, member, unit, rec, handle, env, log, where, settled, last):
                return rec
        return rec
    finally:
        lock.release()


def _run_unit(plan, member, unit, rec, handle, env, log, where, settled, last):
    """The attempts of one run of the member (retried from its checkpoint), recorded in
    `rec`. True when it is done; the member's record is final (and `settled()` called) when
    it is the last run or did not end well."""
    folder = Path(unit.folder)
    folder.mkdir(parents=True, exist_ok=True)
    Path(unit.cwd).mkdir(parents=True, exist_ok=True)
    status_path = Path(member.folder) / records.STATUS_FILE
    name = f"member {member.id}" + (f", stage {unit.stage}" if unit.stage else "")
    stage_rec = rec["stages"][unit.stage] if unit.stage else {}
    if unit.stage:
        rec["stage"] = unit.stage
    budget = 1 + plan.max_retries
    fresh = False
    for k in range(budget):
        resume = not fresh and has_checkpoint(unit)
        fresh = False
        number = sum(1 for a in rec["attempts"] if a.get("stage", "") == unit.stage) + 1
        while (folder / f"attempt-{number}.log").exists():
            number += 1  # an attempt that left no record (its process was killed): kept
        log_path = folder / f"attempt-{number}.log"
        rec.update(state="running", attempt=number, updated=records.now())
        stage_rec.update(state="running")
        records.write_json_atomic(status_path, rec, durable=False)
        code, start, wall = _attempt(plan, unit, member.threads, resume, log_path, handle, env)
        rec["attempts"].append({"number": number, "resume": resume, "exit": code,
                                "start": start, "wall": wall,
                                "log": str(log_path.relative_to(member.folder)),
                                "host": records.hostname(), **(where or {}),
                                **({"stage": unit.stage} if unit.stage else {})})
        # A stop that came after the run had finished (run.json written "completed", the
        # process then ended by the signal on its way out) leaves a whole run: done.
        finished_anyway = code != 0 and records.run_record_finished(folder)
        if handle.stop.is_set() and code != 0 and not finished_anyway:
            settled()
            stage_rec.update(state="interrupted")
            rec.update(state="interrupted", updated=records.now())
            records.write_json_atomic(status_path, rec)
            log(f"{name}: stopped ({describe_exit(code)}); it goes on when the sweep is run "
                "again" + (" (from its last checkpoint)" if has_checkpoint(unit) else ""))
            return False
        what = "done" if finished_anyway and handle.stop.is_set() else classify(code, resume)
        if what == "done":
            stage_rec.update(state=records.DONE, run_time=wall)
            if not last:  # the next stage starts now; the member is running still
                records.write_json_atomic(status_path, rec, durable=False)
                return True
            settled()
            run_time = wall if not unit.stage else \
                sum(s["run_time"] for s in rec["stages"].values())
            rec.update(state=records.DONE, exit=0, run_time=run_time, updated=records.now())
            records.write_json_atomic(status_path, rec)
            return True
        rec["exit"] = code
        left = budget - k - 1
        if what == "give_up" or left == 0:
            settled()
            stage_rec.update(state=records.FAILED)
            rec.update(state=records.FAILED, updated=records.now(),
                       reason=(f"stage {unit.stage}: " if unit.stage else "") +
                       ("not retried: " if what == "give_up" else
                        f"failed {k + 1} times in a row: ") + describe_exit(code))
            records.write_json_atomic(status_path, rec)
            log(f"{name}: FAILED after {k + 1} attempt(s), last {describe_exit(code)}; log "
                f"{log_path}\n" + "\n".join("    " + ln for ln in _tail(log_path).splitlines()))
            return False
        fresh = what == "fresh"
        start_over = fresh or not has_checkpoint(unit)
        log(f"{name}: attempt {number} ended with {describe_exit(code)}; retrying ({left} "
            "left) " + ("from the start" if start_over else "from its last checkpoint"))
    raise AssertionError("unreachable")


def _attempt(plan, unit, threads, resume, log_path, handle, env):
    """One demfem_run; returns (exit status or 'timeout', start time, wall seconds)."""
    full_env = dict(os.environ if env is None else env)
    full_env["OMP_NUM_THREADS"] = str(threads)
    full_env["OPENBLAS_NUM_THREADS"] = str(threads)
    start = records.now()
    t0 = time.monotonic()
    with open(log_path, "w") as out:
        out.write("$ " + " ".join(_command(plan, unit, resume)) + "\n")
        out.flush()
        # Its own session: a Ctrl-C in the sweep's terminal reaches the sweep only, which
        # stops the members itself (SIGINT to demfem_run, which stops its solvers).
        try:
            proc = handle.start(_command(plan, unit, resume), cwd=unit.cwd, stdout=out,
                                stderr=subprocess.STDOUT, env=full_env,
                                start_new_session=True)
        except OSError as e:
            out.write(f"demfem sweep: cannot start {plan.demfem_run}: {e.strerror}\n")
            return EXIT_NOT_STARTED, start, 0.0
        if proc is None:
            return 128 + signal.SIGINT, start, 0.0
        timeout = plan.timeout if plan.timeout > 0 else None
        try:
            code = proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            out.write(f"\ndemfem sweep: attempt stopped after the timeout of {plan.timeout:g} s\n")
            out.flush()
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=STOP_GRACE_S)
            except subprocess.TimeoutExpired:
                handle.kill()
                proc.wait()
            code = "timeout"
    wall = time.monotonic() - t0
    if isinstance(code, int) and code < 0:
        code = 128 - code  # killed by a signal: as a shell reports it
    return code, start, wall
