"""What the tests/system checks that open demfem's output with ParaView's own reader share:
finding ParaView's interpreter (or skipping, ctest's SKIP_RETURN_CODE 77, where it is not
installed), running the check's scene into a fresh folder, running a script under pvpython
offscreen for the JSON it prints, and collecting the failed checks into one report and exit
status."""
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from types import SimpleNamespace

SKIP = 77  # ctest: skipped


def pvpython_or_none():
    """ParaView's pvpython (DEMFEM_PVPYTHON names another one, e.g. a Kitware binary in /opt;
    else pvpython on PATH or /usr/bin/pvpython), or None with the reason printed."""
    p = os.environ.get("DEMFEM_PVPYTHON") or shutil.which("pvpython") or "/usr/bin/pvpython"
    if os.path.isfile(p) and os.access(p, os.X_OK):
        return p
    print(f"pvpython not found ({p}; Debian: python3-paraview, or set DEMFEM_PVPYTHON): skipped")
    return None


def run_demfem(demfem_run, scene, out, *extra):
    """demfem_run SCENE --output-dir OUT [EXTRA...]: the finished process, or None (with its
    exit status and output's end printed) when it failed."""
    r = subprocess.run([demfem_run, scene, "--output-dir", out, *extra], capture_output=True,
                       text=True, timeout=300)
    if r.returncode != 0:
        print("demfem_run failed:", r.returncode, r.stdout[-3000:], r.stderr[-3000:])
        return None
    return r


@contextlib.contextmanager
def scene_run(scene, *extra):
    """The start every check shares (usage: CHECK.py DEMFEM_RUN SOURCE_DIR): demfem_run runs
    SCENE (relative to SOURCE_DIR) with EXTRA into a fresh folder, which lasts as long as the
    `with`. Yields .pvpython, .source, .out (the run folder) and .run (the finished process).
    Exits 77 (skipped) without pvpython, 1 when the run failed."""
    demfem_run, source = sys.argv[1], sys.argv[2]
    pvpython = pvpython_or_none()
    if pvpython is None:
        sys.exit(SKIP)
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "out")
        r = run_demfem(demfem_run, os.path.join(source, scene), out, *extra)
        if r is None:
            sys.exit(1)
        yield SimpleNamespace(pvpython=pvpython, source=source, out=out, run=r)


def offscreen_env():
    """The environment for pvpython reading output: no display (it runs offscreen)."""
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return env


def pvpython_json(pvpython, script, *args):
    """SCRIPT ARGS... under pvpython, offscreen: the JSON object it prints (after whatever
    ParaView prints first), or None (with the script's exit status and output's end printed)
    when it failed."""
    r = subprocess.run([pvpython, script, *args], capture_output=True, text=True, timeout=300,
                       env=offscreen_env())
    if r.returncode != 0:
        print(f"{os.path.basename(script)} failed:", r.returncode, r.stdout[-2000:],
              r.stderr[-4000:])
        return None
    return json.loads(r.stdout[r.stdout.find("{"):])


def inspect_output(pvpython, source, out, values):
    """What ParaView's readers see of the run folder OUT: tools/inspect_output.py OUT --steps
    all --values VALUES (VALUES values of each array); None when it failed."""
    return pvpython_json(pvpython, os.path.join(source, "tools", "inspect_output.py"), out,
                         "--steps", "all", "--values", str(values))


def close(a, b, rel):
    """a and b agree to `rel` of the larger (both 0 agree)."""
    return abs(a - b) <= rel * max(abs(a), abs(b), 1e-300)


class Checks:
    """check(ok, what) records `what` when ok is false and returns ok; report() prints the
    failures and returns the exit status (0: every check held)."""

    def __init__(self):
        self.failures = []

    def __call__(self, ok, what):
        if not ok:
            self.failures.append(what)
        return ok

    def report(self):
        if self.failures:
            print(f"{len(self.failures)} checks failed:")
            for m in self.failures:
                print("  " + m)
            return 1
        print("ok")
        return 0
