#!/usr/bin/python3
"""ctest: tools/sleeper_bed_motion.py's binning (bed_motion) on made-up rocks whose answers are
written out here, and its refusals of bad options and folders (exit 2, naming them).

  check_sleeper_bed_motion.py TOOLS_DIR

The made-up bed: a sleeper footprint x 0.5-1.5 m, centre line y = 0.5 m, bins of 0.25 m (4);
one rock at the middle of each (bin, band, layer) box, plus a second rock in bin 2 of the
first band and layer, and one rock outside the footprint (x = 1.7 m) and one beyond the last
band (2 m from the centre line), which no figure may count. Each rock moves by
dz = -(10 k + i + 100 b) mm (k its bin, i its layer, b its band), the second rock by -40 mm
more than its neighbour, so every mean is known: e.g. bin 2, layer 0, band 0: -(20 + 20 + 40) / 2
= -40 mm. The solid fraction of bin k in the first band and the phi layer 0.60-0.70 m
(the second layer's heights): its one rock there, of volume (k + 1) x 1e-4 m^3, over the box's
0.25 x (2 x 0.1) x 0.1 = 0.005 m^3, so phi_k = 0.02 (k + 1), exact to round-off (tolerance 1e-12). Exit 77 (skipped) without numpy."""

import subprocess
import sys
import tempfile
from pathlib import Path

try:
    import numpy as np
except ImportError:
    print("skipped: numpy is missing (Debian: python3-numpy)")
    sys.exit(77)

TOOLS = Path(sys.argv[1]).resolve()
sys.path.insert(0, str(TOOLS))
import sleeper_bed_motion as tool  # noqa: E402

failures = 0


def check(ok, what):
    global failures
    print(("ok      " if ok else "FAILED  ") + what)
    failures += 0 if ok else 1


LAYERS = [(0.70, 0.80), (0.60, 0.70)]
BANDS = [(0.0, 0.1), (0.2, 0.4)]
FOOT = (0.5, 1.5, 0.5)


def made_up_bed():
    xy, z0, dz, vol, want = [], [], [], [], {}
    for b, (dlo, dhi) in enumerate(BANDS):
        for i, (zl, zh) in enumerate(LAYERS):
            for k in range(4):
                x = 0.5 + 0.25 * k + 0.125
                y = 0.5 + 0.5 * (dlo + dhi) * (-1 if k % 2 else 1)   # both sides of the line
                d = -(10 * k + i + 100 * b)
                xy.append((x, y)), z0.append(0.5 * (zl + zh)), dz.append(d)
                vol.append((k + 1) * 1e-4 if (b, i) == (0, 1) else 1e-4)
                want[(b, i, k)] = (float(d), 1)
    # a second rock in bin 2, band 0, layer 0 (0.70-0.80: outside the phi layer)
    xy.append((1.05, 0.55)), z0.append(0.72), dz.append(-(20 + 40)), vol.append(5e-4)
    want[(0, 0, 2)] = ((-20 - 60) / 2.0, 2)
    # rocks no figure may count: beyond the footprint's end, beyond the last band
    xy.append((1.7, 0.5)), z0.append(0.65), dz.append(-999.0), vol.append(1.0)
    xy.append((1.0, 2.5)), z0.append(0.65), dz.append(-999.0), vol.append(1.0)
    z0 = np.array(z0)
    return np.array(xy), z0, z0 + np.array(dz) * 1e-3, np.array(vol), want


def units():
    xy, z0, z1, vol, want = made_up_bed()
    r = tool.bed_motion(np, xy, z0, z1, vol, FOOT, 0.25, LAYERS, BANDS, (0.60, 0.70))
    check([tuple(round(v, 12) for v in b) for b in r["bins"]] ==
          [(0.5, 0.75), (0.75, 1.0), (1.0, 1.25), (1.25, 1.5)], "four bins of 0.25 m along x")
    ok = all(abs(r["dz_mm"][b][i][k] - d) < 1e-9 and r["count"][b][i][k] == n
             for (b, i, k), (d, n) in want.items())
    check(ok, "each box's mean displacement (mm) and count, the rocks outside left out")
    phi = [0.02 * (k + 1) for k in range(4)]
    check(all(abs(a - b) < 1e-12 for a, b in zip(r["phi"], phi)),
          f"solid fraction per bin {r['phi']} = {phi}")
    empty = tool.bed_motion(np, xy, z0, z1, vol, FOOT, 0.25, [(0.0, 0.1)], BANDS, (0.55, 0.75))
    check(empty["dz_mm"][0][0] == [None] * 4 and empty["count"][0][0] == [0] * 4,
          "a box without rocks has no mean (None) and a count of 0")


def refusals():
    with tempfile.TemporaryDirectory() as d:
        for args, words in ((["--layers", "0.8:0.7"], ["--layers", "LOW < HIGH"]),
                            (["--bands", "a:b"], ["--bands", "LOW:HIGH"]),
                            (["--bin", "0"], ["--bin", "> 0"]),
                            ([], ["no_such_folder", "no such output folder"])):
            r = subprocess.run([sys.executable, str(TOOLS / "sleeper_bed_motion.py"),
                                str(Path(d) / "no_such_folder")] + args,
                               capture_output=True, text=True, cwd=d,
                               env={"PYTHONPATH": str(TOOLS), "PATH": "/usr/bin:/bin"})
            check(r.returncode == 2 and all(w in r.stderr for w in words),
                  f"{' '.join(args) or 'a missing folder'}: exit 2 naming {words}")


units()
refusals()
print(f"{failures} failed" if failures else "all passed")
sys.exit(1 if failures else 0)
