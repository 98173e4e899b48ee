"""The local runner: a process pool sized to the machine. Members are started while their
threads fit in the free cores (a member larger than the machine runs alone) and, for
members with dem.backend = "cuda", while a GPU is free (one DEM per GPU, given to the member
as CUDA_VISIBLE_DEVICES). Ctrl-C (SIGINT) or SIGTERM stops the members cleanly: each
demfem_run gets SIGINT, stops its solvers and keeps its checkpoints."""

import os
import queue
import shutil
import signal
import subprocess
import threading
import time

from sweep import records
from sweep.member import STOP_GRACE_S, Handle, run_member
from sweep.progress import eta_seconds, line
from sweep.sweep_file import SweepError


def machine_cpus():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def machine_gpus():
    """GPU ids: CUDA_VISIBLE_DEVICES when set, else those nvidia-smi lists, else none."""
    env = os.environ.get("CUDA_VISIBLE_DEVICES")
    if env is not None:
        return [g.strip() for g in env.split(",") if g.strip() and g.strip() != "-1"]
    if shutil.which("nvidia-smi"):
        try:
            r = subprocess.run(["nvidia-smi", "--query-gpu=index", "--format=csv,noheader"],
                               capture_output=True, text=True, timeout=20)
            if r.returncode == 0:
                return [g.strip() for g in r.stdout.splitlines() if g.strip()]
        except (OSError, subprocess.TimeoutExpired):
            pass
    return []


class LocalPool:
    def __init__(self, plan, cpus, gpus, jobs, reporter):
        self.plan = plan
        self.cpus = cpus
        self.gpus = list(gpus)
        self.jobs = jobs if jobs > 0 else 1 << 30
        self.reporter = reporter
        self.events = queue.Queue()
        self.stop_signal = None

    def _on_signal(self, sig, frame):
        if self.stop_signal is None:
            self.stop_signal = sig
        else:
            self.reporter.message("demfem sweep: already stopping (members get "
                                  f"{STOP_GRACE_S:g} s to stop cleanly)")

    def run(self, members, done_before):
        """Runs `members` (not done) and returns {member id: record}; `done_before` are the
        run times of members finished in earlier runs (for the ETA)."""
        need_gpu = [m for m in members if m.gpu]
        if need_gpu and not self.gpus:
            raise SweepError(
                f"{len(need_gpu)} member(s) (e.g. {need_gpu[0].id}) use dem.backend = \"cuda\" "
                "but no GPU was found (CUDA_VISIBLE_DEVICES, nvidia-smi); name them with --gpus")
        queued = list(members)
        running = {}  # id -> (member, handle, thread, start, gpu)
        free_gpus = list(self.gpus)
        used_cpus = 0
        results = {}
        run_times = list(done_before)
        counts = {"done": 0, "failed": 0}
        total = len(members)
        old = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        stopping_since = None
        # Members that can run at once (for the ETA).
        capacity = max(1, self.cpus // max(1, min((m.threads for m in members), default=1)))
        if need_gpu:
            capacity = min(capacity, len(self.gpus)) if len(need_gpu) == total else capacity
        try:
            changed = True
            freed = set()  # running members whose process has ended (record being written)
            while queued or running:
                # Start what fits.
                if self.stop_signal is None:
                    i = 0
                    while i < len(queued) and len(running) - len(freed) < self.jobs:
                        m = queued[i]
                        fits = used_cpus + m.threads <= self.cpus or len(running) == len(freed)
                        if fits and (not m.gpu or free_gpus):
                            queued.pop(i)
                            gpu = free_gpus.pop(0) if m.gpu else None
                            used_cpus += m.threads
                            running[m.id] = self._start(m, gpu)
                            changed = True
                        else:
                            i += 1
                elif stopping_since is None:
                    stopping_since = time.monotonic()
                    self.reporter.message(
                        f"demfem sweep: {signal.Signals(self.stop_signal).name}: stopping "
                        f"{len(running)} running member(s); {len(queued)} not started")
                    for (_, h, _, _, _) in running.values():
                        h.interrupt(signal.SIGINT)
                    queued.clear()
                elif time.monotonic() - stopping_since > STOP_GRACE_S:
                    for (_, h, _, _, _) in running.values():
                        h.kill()
                if not running and not queued:
                    break
                now = time.monotonic()
                active = [r for k, r in running.items() if k not in freed]
                slots = min(self.jobs, capacity, len(active) + len(queued))
                eta = eta_seconds(run_times, len(queued), [now - r[3] for r in active], slots)
                self.reporter.show(line(self.plan.name, {
                    "done": counts["done"], "running": len(active), "failed": counts["failed"],
                    "queued": len(queued)}, total, eta), force=changed)
                changed = False
                try:
                    kind, mid, rec, err = self.events.get(timeout=0.25)
                except queue.Empty:
                    continue
                if kind == "settled" or mid not in freed:
                    # Its demfem_run has ended: the cores and the GPU are free for the next.
                    freed.add(mid)
                    m, _, _, _, gpu = running[mid]
                    used_cpus -= m.threads
                    if gpu is not None:
                        free_gpus.append(gpu)
                if kind == "settled":
                    continue
                changed = True
                freed.discard(mid)
                m, h, t, start, gpu = running.pop(mid)
                t.join()
                if err is not None:
                    raise err
                results[mid] = rec
                state = rec["state"] if rec else "running elsewhere"
                if state == records.DONE:
                    counts["done"] += 1
                    run_times.append(rec["run_time"])
                    runs = (f"{len(rec['stages'])} stages, {len(rec['attempts'])} runs"
                            if rec.get("stages") else f"attempt {len(rec['attempts'])}")
                    self.reporter.message(f"member {mid} done in {rec['run_time']:.2f} s "
                                          f"({runs})")
                elif state == records.FAILED:
                    counts["failed"] += 1
            self.reporter.show(line(self.plan.name, {
                "done": counts["done"], "running": 0, "failed": counts["failed"],
                "queued": 0}, total, 0.0), force=True)
        finally:
            for s, h in old.items():
                signal.signal(s, h)
            self.reporter.finish()
        return results

    def _start(self, member, gpu):
        handle = Handle()
        env = dict(os.environ)
        if gpu is not None:
            env["CUDA_VISIBLE_DEVICES"] = gpu

        def work():
            try:
                rec = run_member(self.plan, member, handle, env, log=self.reporter.message,
                                 where={"gpu": gpu} if gpu is not None else None,
                                 settled=lambda: self.events.put(("settled", member.id, None,
                                                                  None)))
                self.events.put(("end", member.id, rec, None))
            except BaseException as e:  # reported by the main thread
                self.events.put(("end", member.id, None, e))

        t = threading.Thread(target=work, name=member.id, daemon=True)
        t.start()
        return member, handle, t, time.monotonic(), gpu
