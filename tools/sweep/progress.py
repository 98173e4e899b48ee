"""Counting members by state and estimating the time left from finished members' run times."""

import math
import sys
import threading
import time

STATES = ("done", "running", "failed", "queued")


def eta_seconds(run_times, queued, running_elapsed, slots):
    """Seconds until the last member ends: the mean run time of finished members for each
    queued one, what is left of it for each running one, spread over `slots` members at a
    time. None while no member has finished."""
    if not run_times:
        return None
    mean = math.fsum(run_times) / len(run_times)
    work = queued * mean + math.fsum(max(mean - e, 0.0) for e in running_elapsed)
    return work / max(1, slots)


def format_duration(s):
    if s is None:
        return "unknown"
    s = int(round(s))
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}" if m else f"{sec} s"


def line(name, counts, total, eta):
    parts = ", ".join(f"{counts.get(k, 0)} {k}" for k in STATES)
    return f"sweep {name}: {parts} (of {total}); ETA {format_duration(eta)}"


class Reporter:
    """Prints progress lines: in place on a terminal, else at most one per `interval` s
    (and always when asked to)."""

    def __init__(self, interval, out=sys.stdout):
        self.interval = interval
        self.out = out
        self.terminal = out.isatty()
        self.last = -math.inf
        self.open = False
        self.lock = threading.Lock()  # members' threads print messages too

    def show(self, text, force=False):
        with self.lock:
            self._show(text, force)

    def _show(self, text, force):
        t = time.monotonic()
        if self.terminal:
            self.out.write("\r\033[K" + text)
            self.out.flush()
            self.open = True
            return
        if force or t - self.last >= self.interval:
            self.last = t
            self.out.write(text + "\n")
            self.out.flush()

    def message(self, text):
        with self.lock:
            self._message(text)

    def _message(self, text):
        if self.open:
            self.out.write("\r\033[K")
            self.open = False
        self.out.write(text + "\n")
        self.out.flush()

    def finish(self):
        with self.lock:
            self._finish()

    def _finish(self):
        if self.open:
            self.out.write("\n")
            self.out.flush()
            self.open = False
