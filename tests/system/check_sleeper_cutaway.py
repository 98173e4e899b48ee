"""ctest check of tools/sleeper_cutaway.py (ParaView pictures of the sleeper's bed cut open) on
the small sleeper chain (cases/sleeper_mini.toml, written every 2 ms).

usage: check_sleeper_cutaway.py DEMFEM_RUN SOURCE_DIR

Runs the chain in a fresh folder (its report included), then the cutaway under xvfb-run pvbatch,
and checks against references of its own: the default picture time is the 132 kN level before
the cycles, 0.6 of the ramp after the pattern's start, written out from the pattern's formula
(docs/scene_fem.md): 0.1 + 0.6 x 0.03 = 0.118 s, the displacement counted from the start,
0.1 s; the cut lies on the sleeper's centre line, y = 0.5 m (the mesh's y 0.4-0.6 m); the
rocks shown are those whose centre lies at y >= 0.5 m at 0.118 s, counted here from the particle
snapshot with demfem_post (another reader than ParaView's); each PNG is a picture of the scene,
not a blank view: over 5 % of its pixels are not background white, and the pressure cells'
magenta covers over 0.1 %. A time outside the run is refused with exit 2 and no picture.
Exit 77 (skipped) without pvbatch, xvfb-run or matplotlib (the report's plots and the PNG
reader)."""

import os
import re
import shutil
import subprocess
import sys
import tempfile

SKIP = 77
demfem_run, source = sys.argv[1], sys.argv[2]
for tool in ("pvbatch", "xvfb-run"):
    if shutil.which(tool) is None:
        print(f"{tool} not found (Debian: paraview, xvfb): skipped")
        sys.exit(SKIP)
try:
    import matplotlib.image
except ImportError:
    print("matplotlib is not installed (Debian: python3-matplotlib): skipped")
    sys.exit(SKIP)
sys.path.insert(0, os.path.join(source, "tools"))
import demfem_post  # noqa: E402

PICTURE_T, START_T, Y_CUT = 0.118, 0.1, 0.5
fail = []


def cutaway(out, *args):
    """The cutaway under xvfb-run. xvfb-run -a can pick a display that another xvfb-run on the
    machine takes at the same moment (seen in a full ctest run): ParaView then aborts at its
    start (SIGABRT, "bad X server connection"). That is the machine, not the script: run it
    again, at most twice, and say so."""
    for attempt in range(3):
        r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", "pvbatch",
                            os.path.join(source, "tools", "sleeper_cutaway.py"), out, *args],
                           capture_output=True, text=True, timeout=300)
        text = r.stdout + r.stderr
        if "bad X server connection" not in text and "Signal: SIGABRT" not in text:
            return r
        print(f"(attempt {attempt + 1}: pvbatch lost its virtual display; again)", flush=True)
    return r


def picture_fractions(path):
    """(share of pixels not white, share of the cells' magenta) of a PNG."""
    img = matplotlib.image.imread(path)[:, :, :3]
    n = img.shape[0] * img.shape[1]
    r, g, b = img[:, :, 0], img[:, :, 1], img[:, :, 2]
    not_white = ((r < 0.95) | (g < 0.95) | (b < 0.95)).sum() / n
    magenta = ((r > 0.45) & (g < 0.25) & (b > 0.25) & (r > b)).sum() / n
    return not_white, magenta


with tempfile.TemporaryDirectory() as d:
    out = os.path.join(d, "load")
    r = subprocess.run([demfem_run, os.path.join(source, "cases", "sleeper_mini.toml"), "--quiet",
                        "--output-dir", out, "--set", "run.output_interval=0.002", "--set",
                        "dem.output.interval=0.002"], cwd=d, capture_output=True, text=True,
                       timeout=1200)
    if r.returncode != 0:
        print("the sleeper mini chain failed:", r.returncode, r.stdout[-3000:], r.stderr[-3000:])
        sys.exit(1)
    r = cutaway(out, "--png", os.path.join(d, "cut"))
    m = re.search(r"picture at t = (\S+) s, the rocks' displacement from t = (\S+) s, (\d+) of "
                  r"(\d+) rocks behind y = (\S+) m", r.stdout)
    if r.returncode != 0 or m is None:
        print("sleeper_cutaway.py failed:", r.returncode, r.stdout[-3000:], r.stderr[-3000:])
        sys.exit(1)
    t, t_ref, shown, total, y_cut = (float(m.group(k)) for k in range(1, 6))
    if abs(t - PICTURE_T) > 1e-9 or abs(t_ref - START_T) > 1e-9:
        fail.append(f"picture at {t} s from {t_ref} s; expected {PICTURE_T} s from {START_T} s")
    if abs(y_cut - Y_CUT) > 1e-9:
        fail.append(f"cut at y = {y_cut} m, expected {Y_CUT} m")
    rocks = demfem_post.open(out).particles(PICTURE_T)
    behind = int((rocks.points[:, 1] >= Y_CUT).sum())
    if (shown, total) != (behind, len(rocks.points)):
        fail.append(f"{shown:g} of {total:g} rocks shown; the snapshot has {behind} of "
                    f"{len(rocks.points)} with centre y >= {Y_CUT} m")
    for name in ("front", "oblique"):
        path = os.path.join(d, f"cut_{name}.png")
        if not os.path.isfile(path):
            fail.append(f"no {path}")
            continue
        not_white, magenta = picture_fractions(path)
        if not_white < 0.05 or magenta < 0.001:
            fail.append(f"{name}: {100 * not_white:.1f} % of the pixels not white, "
                        f"{100 * magenta:.2f} % the cells' magenta: a blank picture?")
    r = cutaway(out, "--time", "99", "--png", os.path.join(d, "late"))
    if r.returncode != 2 or "99 s is outside" not in r.stderr or \
            any(f.startswith("late") for f in os.listdir(d)):
        fail.append(f"a time outside the run: exit {r.returncode}, {r.stderr[-500:]}")
if fail:
    print("\n".join(fail))
    sys.exit(1)
print("ok")
