"""ctest check of tools/sleeper_report.py's strain gauges and --set, on a made-up output of the
small sleeper case (cases/sleeper_mini.toml): the monitor's probes move as a sleeper in pure
bending about a neutral axis at mid height, u_x = -kappa (z - z_n) (x - 1.6) with the
curvature kappa(t) = k1 t: the bottom fibre's axial strain is then exactly
kappa (z_n - z_bottom) = kappa h / 2 at every gauge (the analytical reference, independent of
the gauge's length and place). A `--set` of the pattern's time scale moves the cycle marks;
a malformed --set is refused with exit 2. Exit 77 (skipped) without matplotlib."""

import json
import math
import os
import subprocess
import sys
import tempfile
import tomllib

from module_or_skip import module_or_skip

module_or_skip("matplotlib", "python3-matplotlib")

script, scene = sys.argv[1], sys.argv[2]
with open(scene, "rb") as f:
    sc = tomllib.load(f)
probes = sc["fem"]["monitor"]["probes"]
gauges = sorted({p["name"][3:-2] for p in probes if p["name"].startswith("sg_")})
if len(gauges) < 3:
    print(f"{scene}: expected the three strain gauges (centre, seat1, seat2), found {gauges}")
    sys.exit(1)
H = 0.18                      # the sleeper's height
K1 = 2e-3                     # 1/m per s: the curvature grows linearly in time
fail = []
with tempfile.TemporaryDirectory() as d:
    times = [0.001 * i for i in range(401)]  # to 0.4 s (the pattern at time scale 1: 0.1-0.22)
    z_bottom = probes[0]["point"][2]
    z_n = z_bottom + H / 2
    with open(os.path.join(d, "fem_monitor.csv"), "w") as f:
        f.write("time," + ",".join(f"{p['name']}_{c}" for p in probes for c in ("ux", "uy", "uz"))
                + "\n")
        for t in times:
            row = [t]
            for p in probes:
                x, _, z = p["point"]
                row += [-K1 * t * (z - z_n) * (x - 1.6), 0.0, -0.01 * t]
            f.write(",".join(repr(v) for v in row) + "\n")
    with open(os.path.join(d, "fem_series.csv"), "w") as f:
        f.write("time,max_principal_strain\n")
        for t in times[::50]:
            f.write(f"{t!r},{K1 * t * H / 2!r}\n")
    for name in ["base"] + [f"cell{k}" for k in range(1, 6)]:
        with open(os.path.join(d, f"sensor_{name}.csv"), "w") as f:
            f.write("time,fx,fy,fz\n")
            for t in times[::10]:
                f.write(f"{t!r},0,0,-1000\n")
    r = subprocess.run([sys.executable, script, d, "--scene", scene, "--hold", "0.3,0.4"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        print("report failed:", r.returncode, r.stdout, r.stderr)
        sys.exit(1)
    rep = json.load(open(os.path.join(d, "sleeper_report.json")))
    want_final = K1 * times[-1] * H / 2
    for g in gauges:
        got = rep["strain"][g]["final"]
        # the report snaps the probe points to mesh nodes (x), the same x enter u_x here only
        # through the points: a gauge of points off the nodes would differ by dx / gauge
        if not math.isclose(got, want_final, rel_tol=1e-3):
            fail.append(f"gauge {g}: final strain {got}, analytical {want_final}")
        hold = rep["hold"]["strain"][g]
        want_hold = K1 * 0.35 * H / 2  # mean of a linear function over [0.3, 0.4]
        if not math.isclose(hold, want_hold, rel_tol=1e-3):
            fail.append(f"gauge {g}: hold strain {hold}, analytical {want_hold}")
    png = os.path.join(d, "sleeper_strain.png")
    if not os.path.isfile(png) or open(png, "rb").read(8) != b"\x89PNG\r\n\x1a\n":
        fail.append("no sleeper_strain.png")
    # --set reaches the report: at time scale 1 the cycle minima lie at 0.13 + k 0.01 s; at
    # time scale 2 at 0.16 + k 0.02 s, of which those up to 0.4 s are in the output
    cyc1 = [c["cycle"] for c in rep["cycles"]]
    r = subprocess.run([sys.executable, script, d, "--scene", scene, "--set",
                        "fem.pressures[1].amplitude.time_scale=2.0", "--set",
                        "fem.pressures[2].amplitude.time_scale=2.0"], capture_output=True, text=True)
    rep2 = json.load(open(os.path.join(d, "sleeper_report.json")))
    if r.returncode != 0 or cyc1 != [0, 1, 2, 3, 4, 5, 6] or \
            [c["cycle"] for c in rep2["cycles"]] != [0, 1, 2, 3, 4, 5, 6] or \
            rep2["cycles"][1]["settlement_mm"] >= rep["cycles"][1]["settlement_mm"]:
        fail.append(f"--set time_scale: exit {r.returncode}, cycles {cyc1} -> {rep2['cycles']}")
    r = subprocess.run([sys.executable, script, d, "--scene", scene, "--set", "fem.nothere[3]=1"],
                       capture_output=True, text=True)
    if r.returncode != 2 or "fem.nothere" not in r.stderr:
        fail.append(f"a bad --set was not refused: {r.returncode} {r.stderr}")
if fail:
    print("\n".join(fail))
    sys.exit(1)
print("ok")
