"""Running one member: demfem_run in the member's folder, retried from its last committed
checkpoint when it fails, with the member's record written atomically after every change.
The same code runs a member in the local pool and in a Slurm array task."""

import os
import signal
import subprocess
import threading
import time
from pathlib import Path

from sweep import records
from sweep.exit_status import EXIT_BAD_INPUT, EXIT_BLOW_UP, EXIT_NOT_STARTED, NAMES
from sweep.plan import check_identity, write_identity

STOP_GRACE_S = 20.0  # after SIGINT/SIGTERM, how long a member may take to stop cleanly


def has_checkpoint(member):
    """True when the member's checkpoint folder holds a committed checkpoint (a manifest);
    demfem_run --resume verifies it and falls back to older ones itself."""
    if not member.checkpoints:
        return False
    return any((Path(member.folder) / member.checkpoints).glob("step-*/manifest.json"))


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


def _command(plan, member, resume):
    cmd = [plan.demfem_run, plan.scene, "--output-dir", member.folder]
    for o in member.overrides:
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
    """Runs the member until it is done, fails for good, or is stopped through `handle`.
    Returns its record (state 'done', 'failed', 'interrupted'), or None when another
    process holds the member (it is running elsewhere). `settled()` is called as soon as the
    last demfem_run has ended, before the final record is written (a pool can start the
    next member meanwhile: the durable write costs tens of ms on a busy disk)."""
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
        status_path = folder / records.STATUS_FILE
        budget = 1 + plan.max_retries
        fresh = False
        for k in range(budget):
            resume = not fresh and has_checkpoint(member)
            fresh = False
            number = len(rec["attempts"]) + 1
            while (folder / f"attempt-{number}.log").exists():
                number += 1  # an attempt that left no record (its process was killed): kept
            log_path = folder / f"attempt-{number}.log"
            rec.update(state="running", attempt=number, updated=records.now())
            records.write_json_atomic(status_path, rec, durable=False)
            code, start, wall = _attempt(plan, member, resume, log_path, handle, env)
            rec["attempts"].append({"number": number, "resume": resume, "exit": code,
                                    "start": start, "wall": wall, "log": log_path.name,
                                    "host": records.hostname(), **(where or {})})
            # A stop that came after the run had finished (run.json written "completed", the
            # process then ended by the signal on its way out) leaves a whole run: done.
            finished_anyway = code != 0 and records.run_record_finished(folder)
            if handle.stop.is_set() and code != 0 and not finished_anyway:
                settled()
                rec.update(state="interrupted", updated=records.now())
                records.write_json_atomic(status_path, rec)
                log(f"member {member.id}: stopped ({describe_exit(code)}); it goes on when the "
                    "sweep is run again" + (" (from its last checkpoint)" if has_checkpoint(member)
                                            else ""))
                return rec
            what = "done" if finished_anyway and handle.stop.is_set() else classify(code, resume)
            if what == "done":
                settled()
                rec.update(state=records.DONE, exit=0, run_time=wall, updated=records.now())
                records.write_json_atomic(status_path, rec)
                return rec
            rec["exit"] = code
            left = budget - k - 1
            if what == "give_up" or left == 0:
                settled()
                rec.update(state=records.FAILED, updated=records.now(),
                           reason=("not retried: " if what == "give_up" else
                                   f"failed {k + 1} times in a row: ") + describe_exit(code))
                records.write_json_atomic(status_path, rec)
                log(f"member {member.id}: FAILED after {k + 1} attempt(s), last "
                    f"{describe_exit(code)}; log {log_path}\n" +
                    "\n".join("    " + ln for ln in _tail(log_path).splitlines()))
                return rec
            fresh = what == "fresh"
            start_over = fresh or not has_checkpoint(member)
            log(f"member {member.id}: attempt {number} ended with {describe_exit(code)}; "
                f"retrying ({left} left) " +
                ("from the start" if start_over else "from its last checkpoint"))
        raise AssertionError("unreachable")
    finally:
        lock.release()


def _attempt(plan, member, resume, log_path, handle, env):
    """One demfem_run; returns (exit status or 'timeout', start time, wall seconds)."""
    full_env = dict(os.environ if env is None else env)
    full_env["OMP_NUM_THREADS"] = str(member.threads)
    full_env["OPENBLAS_NUM_THREADS"] = str(member.threads)
    start = records.now()
    t0 = time.monotonic()
    with open(log_path, "w") as out:
        out.write("$ " + " ".join(_command(plan, member, resume)) + "\n")
        out.flush()
        # Its own session: a Ctrl-C in the sweep's terminal reaches the sweep only, which
        # stops the members itself (SIGINT to demfem_run, which stops its solvers).
        try:
            proc = handle.start(_command(plan, member, resume), cwd=member.folder, stdout=out,
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
