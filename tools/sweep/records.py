"""What the sweep writes into each member's folder, and how it tells whether a member is
finished: its own record (status.json, written atomically by the process that ran the
member), or the run record run.json that demfem_run may write itself."""

import errno
import fcntl
import json
import os
import socket
import threading
import time
from pathlib import Path

STATUS_FILE = "status.json"     # the sweep's record of the member (state, attempts)
IDENTITY_FILE = "member.json"   # what the member is: scene, its hash, the overrides
LOCK_FILE = "member.lock"       # held while a process runs the member
RUN_RECORD = "run.json"         # demfem_run's own run record

# Final states; "running" and "interrupted" are not.
DONE, FAILED = "done", "failed"


def write_json_atomic(path, obj, durable=True):
    """Writes JSON under a temporary name and renames it over `path`: a reader sees the old
    file or the new one, never a part. `durable`: fsync the file and the folder too, so the
    record survives a crash of the machine (final states; a lost "running" record only makes
    the member run again, so those skip the cost, tens of ms on a busy disk)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    with open(tmp, "w") as f:
        json.dump(obj, f, indent=1, sort_keys=True)
        f.write("\n")
        f.flush()
        if durable:
            os.fsync(f.fileno())
    os.replace(tmp, path)
    if not durable:
        return
    try:
        fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        pass


def read_json(path):
    """The JSON object in `path`, or None when it is missing or not a JSON object."""
    try:
        with open(path) as f:
            obj = json.load(f)
    except (OSError, ValueError):
        return None
    return obj if isinstance(obj, dict) else None


def run_record_finished(folder):
    """True when demfem_run's run record (run.json, coupler/src/launch/run_record.cpp) says the run
    finished successfully: status "completed" and exit_code 0."""
    rec = read_json(Path(folder) / RUN_RECORD)
    if not rec:
        return False
    status = str(rec.get("status", "")).lower()
    return status == "completed" and rec.get("exit_code") == 0


def pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def hostname():
    return socket.gethostname()


def member_state(folder):
    """(state, record) of a member folder: 'new' (never started), 'running' (a live
    process holds it), 'interrupted' (started, stopped before it finished: resumed next
    time), 'done' or 'failed'. A 'running' record of this host whose process is gone, and a
    record-less folder, are 'interrupted' unless run.json says the run finished."""
    folder = Path(folder)
    rec = read_json(folder / STATUS_FILE)
    state = rec.get("state") if rec else None
    if state in (DONE, FAILED):
        return state, rec
    if state == "running" and rec.get("host") == hostname():
        pid = rec.get("pid")
        if not isinstance(pid, int) or not pid_alive(pid) or not member_locked(folder):
            state = "interrupted"  # the process that ran it is gone
    if state != "running" and run_record_finished(folder):
        return DONE, rec or {}
    if state is None:
        return ("new" if not folder.exists() or not any(folder.glob("attempt-*.log"))
                else "interrupted"), rec or {}
    return state, rec


class MemberLock:
    """An exclusive flock on the member folder's lock file, so that no two processes (two
    sweeps, or a resubmitted Slurm task and a late old one) run the same member."""

    def __init__(self, folder):
        self.path = Path(folder) / LOCK_FILE
        self.fd = None

    def acquire(self):
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            os.close(self.fd)
            self.fd = None
            if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                return False
            raise
        return True

    def release(self):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def member_locked(folder):
    lock = MemberLock(folder)
    try:
        if lock.acquire():
            lock.release()
            return False
    except OSError:
        return False
    return True


def now():
    return time.time()
