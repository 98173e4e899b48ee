"""ctest check of tools/sleeper_report.py's cell pressures at the thesis's load levels (fig. 6.14:
44 and 132 kN on the ramps before and after the cycles), on a made-up output of the small
sleeper case (cases/sleeper_mini.toml).

usage: check_sleeper_levels.py tools/sleeper_report.py cases/sleeper_mini.toml

The reference moments are written out here from the pattern of docs/scene_fem.md, not taken
from the report: sleeper_mini's pattern starts at 0.1 s, time scale 1, ramps of 0.03 s
(F = peak tau / T_r), cycles 0.03-0.09 s (T_u = 0); its peak is 22 kN (load scale 0.1), so the
thesis's 44 and 132 kN of its 220 kN stand at 0.2 and 0.6 of the peak: 4.4 and 13.2 kN here,
at t = 0.1 + 0.2 x 0.03 = 0.106 s and 0.118 s before the cycles, and 0.1 + 0.09 + 0.006 =
0.196 s and 0.208 s after; the first and the last of its six cycles (100 Hz,
F = cycle_min + (cycle_max - cycle_min)(1 - cos 2 pi f (tau - 0.03)) / 2) peak at cycle_max =
4.4 kN (the thesis's 44 kN) at t = 0.1 + 0.03 + 0.005 = 0.135 s and 0.1 + 0.03 + 0.055 =
0.185 s. The cells' pressures are linear in time (cell 3: 1000 t kPa; cell 1:
112 kPa; the others 10 k kPa), so the mean over a window symmetric about a moment is the
value at it, exact to round-off (tolerance 1e-9 relative); cell 1 is the largest at 0.106 s
(112 > 106), the middle cell 3 at the later moments. Sampled every 0.2 ms the report
averages the samples within +-0.6 ms (2 % of the ramp); sampled every 5 ms, with no sample in
that window, it takes the nearest one (0.105, 0.12 s; 0.135 s is a sample), and a run that ends
at 0.15 s has only the moments up to the first cycle's peak. --beside draws another reported
run beside this one (its cells' depth in the json); a folder without a report is refused with
exit 2, the report left as it was. Stress boxes (packing sensors named stress* with contacts = true,
appended to a copy of the scene): their stress_zz (Pa) is read as kPa at the same moments and in
the hold, box A 215 kPa, the middle box B 2000 t kPa, box C 30 kPa, so A is the largest at
0.106 s (212 < 215) and B from 0.118 s; their centre depth is the bed top less the box's middle
z. Exit 77 (skipped) without matplotlib."""

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import tomllib

from module_or_skip import module_or_skip

module_or_skip("matplotlib", "python3-matplotlib")

script, scene = sys.argv[1], sys.argv[2]
with open(scene, "rb") as f:
    probes = tomllib.load(f)["fem"]["monitor"]["probes"]
CELL_AREA = 0.22 * 0.22        # m^2, sleeper_mini's cells (table 6.1)
BED_TOP = 0.47                 # m, the made-up under_sleeper top at t = 0
CELL_TOP = 0.31                # m, sleeper_mini's cells' tops (scene)
MOMENTS = [(44.0, "before", 4.4e3, 0.106), (132.0, "before", 13.2e3, 0.118),
           (44.0, "first_cycle", 4.4e3, 0.135), (44.0, "last_cycle", 4.4e3, 0.185),
           (44.0, "after", 4.4e3, 0.196), (132.0, "after", 13.2e3, 0.208)]


def pressure_kpa(k, t):
    return {1: 112.0, 3: 1000.0 * t}.get(k, 10.0 * k)


def write_output(d, sample, end):
    times = [sample * i for i in range(round(end / sample) + 1)]
    with open(os.path.join(d, "fem_monitor.csv"), "w") as f:
        f.write("time," + ",".join(f"{p['name']}_{c}" for p in probes for c in ("ux", "uy", "uz"))
                + "\n")
        for t in times:
            f.write(",".join(repr(v) for v in [t] + [0.0, 0.0, -0.01 * t] * len(probes)) + "\n")
    for k in range(1, 6):
        with open(os.path.join(d, f"sensor_cell{k}.csv"), "w") as f:
            f.write("time,fx,fy,fz\n")
            for t in times:
                f.write(f"{t!r},0,0,{-pressure_kpa(k, t) * 1e3 * CELL_AREA!r}\n")
    with open(os.path.join(d, "sensor_base.csv"), "w") as f:
        f.write("time,fx,fy,fz\n" + "".join(f"{t!r},0,0,-1000\n" for t in times))
    with open(os.path.join(d, "sensor_under_sleeper.csv"), "w") as f:
        f.write("time,particles,solid_fraction,coordination,top\n" +
                "".join(f"{t!r},100,0.55,4.0,{BED_TOP!r}\n" for t in times))


STRESS_BOXES = {"stressA": (0.8, 215.0), "stressB": (1.6, None), "stressC": (2.4, 30.0)}
STRESS_Z = (0.38, 0.42)        # m: the boxes' z range, centre depth BED_TOP - 0.40


def stress_kpa(name, t):
    return STRESS_BOXES[name][1] if STRESS_BOXES[name][1] is not None else 2000.0 * t


def scene_with_stress_boxes(d):
    """A copy of the scene in d (its mesh file by absolute path) with the three stress boxes."""
    folder = os.path.dirname(os.path.abspath(scene))
    text = open(scene).read().replace('file = "geometry/',
                                      f'file = "{folder}/geometry/')
    for name, (x, _) in STRESS_BOXES.items():
        text += (f'\n[[dem.sensors]]\nname = "{name}"\nkind = "packing"\ncontacts = true\n'
                 f'lo = [{x - 0.1}, 0.4, {STRESS_Z[0]}]\nhi = [{x + 0.1}, 0.6, {STRESS_Z[1]}]\n'
                 'interval = 0.0002\n')
    path = os.path.join(d, "scene_stress.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def write_stress(d, sample, end):
    times = [sample * i for i in range(round(end / sample) + 1)]
    for name in STRESS_BOXES:
        with open(os.path.join(d, f"sensor_{name}.csv"), "w") as f:
            f.write("time,particles,solid_fraction,coordination,top,stress_zz\n" + "".join(
                f"{t!r},50,0.6,4.5,0.45,{stress_kpa(name, t) * 1e3!r}\n" for t in times))


def check_levels(rep, want_times, label):
    fail = []
    got = [(m["level_kN"], m["stage"]) for m in rep["load_levels"]]
    want = [(lv, st) for lv, st, _, _ in MOMENTS][:len(want_times)]
    if got != want:
        return [f"{label}: levels {got}, expected {want}"]
    for m, (lv, st, load, tm), ts in zip(rep["load_levels"], MOMENTS, want_times):
        if not math.isclose(m["time"], tm, rel_tol=1e-12) or \
                not math.isclose(m["load_per_seat_N"], load, rel_tol=1e-12):
            fail.append(f"{label} {lv} kN {st}: moment {m['time']} s, load {m['load_per_seat_N']}"
                        f" N; expected {tm} s, {load} N")
        for k in range(1, 6):
            p = m["cell_pressure_kPa"][f"cell{k}"]
            if not math.isclose(p, pressure_kpa(k, ts), rel_tol=1e-9):
                fail.append(f"{label} {lv} kN {st}: cell{k} {p} kPa, expected "
                            f"{pressure_kpa(k, ts)} (at t = {ts} s)")
        largest = "cell1" if tm < 0.11 else "cell3"
        if m["largest_cell"] != largest or m["middle_cell_largest"] != (largest == "cell3"):
            fail.append(f"{label} {lv} kN {st}: largest {m['largest_cell']} (middle "
                        f"{m['middle_cell_largest']}), expected {largest}")
        if not math.isclose(m["settlement_mm"], -10.0 * ts, rel_tol=1e-9):
            fail.append(f"{label}: settlement {m['settlement_mm']} mm at {tm} s")
    return fail


def run_report(d, scene_path=None, extra=()):
    r = subprocess.run([sys.executable, script, d, "--scene", scene_path or scene, *extra],
                       capture_output=True, text=True)
    if r.returncode != 0:
        print("report failed:", r.returncode, r.stdout, r.stderr)
        sys.exit(1)
    with open(os.path.join(d, "sleeper_report.json")) as f:
        return json.load(f), r.stdout


fail = []
with tempfile.TemporaryDirectory() as d:
    write_output(d, 2e-4, 0.45)
    rep, text = run_report(d)
    fail += check_levels(rep, [tm for _, _, _, tm in MOMENTS], "sampled every 0.2 ms")
    if any(min(m["cell_samples"].values()) != 7 for m in rep["load_levels"]):
        fail.append("0.2 ms: expected 7 samples in each +-0.6 ms window: "
                    f"{[m['cell_samples'] for m in rep['load_levels']]}")
    for c in rep["cells"]["cells"]:
        if not math.isclose(c["depth_m"], BED_TOP - CELL_TOP, rel_tol=1e-12):
            fail.append(f"{c['name']}: depth {c['depth_m']} m, expected {BED_TOP - CELL_TOP}")
    if "132 kN level on the ramp after the cycles" not in text or \
            "44 kN level at the last cycle's peak" not in text or "(the middle cell)" not in text:
        fail.append("the text report lacks the levels: " + text)
    png = os.path.join(d, "cell_pressures_levels.png")
    if not os.path.isfile(png) or open(png, "rb").read(8) != b"\x89PNG\r\n\x1a\n":
        fail.append("no cell_pressures_levels.png")
    # --beside: another reported run (here the same one) drawn beside, named in the json; a
    # folder without a report is refused (exit 2) before anything is written
    with tempfile.TemporaryDirectory() as other:
        shutil.copy(os.path.join(d, "sleeper_report.json"), other)
        r = subprocess.run([sys.executable, script, d, "--scene", scene, "--beside", other],
                           capture_output=True, text=True)
        with open(os.path.join(d, "sleeper_report.json")) as f:
            beside = json.load(f).get("beside")
        if r.returncode != 0 or beside != [{"output": other, "cells_depth_m": "0.160"}]:
            fail.append(f"--beside: exit {r.returncode} {r.stderr[-300:]}, json {beside}")
        before = open(os.path.join(d, "sleeper_report.json")).read()
        r = subprocess.run([sys.executable, script, d, "--scene", scene, "--beside",
                            os.path.join(other, "none")], capture_output=True, text=True)
        if r.returncode != 2 or "sleeper_report.json" not in r.stderr or \
                open(os.path.join(d, "sleeper_report.json")).read() != before:
            fail.append(f"a --beside without a report: exit {r.returncode}, {r.stderr[-300:]}")
with tempfile.TemporaryDirectory() as d:
    write_output(d, 2e-4, 0.45)
    write_stress(d, 2e-4, 0.45)
    rep, text = run_report(d, scene_with_stress_boxes(d), ["--hold", "0.3,0.4"])
    fail += check_levels(rep, [tm for _, _, _, tm in MOMENTS], "with stress boxes")
    for m in rep["load_levels"]:
        for name in STRESS_BOXES:
            got, want = m["stress_zz_kPa"][name], stress_kpa(name, m["time"])
            if not math.isclose(got, want, rel_tol=1e-9):
                fail.append(f"stress box {name} at {m['time']} s: {got} kPa, expected {want}")
        largest = "stressA" if m["time"] < 0.11 else "stressB"
        if m["largest_stress_box"] != largest or \
                m["middle_stress_box_largest"] != (largest == "stressB"):
            fail.append(f"at {m['time']} s: largest stress box {m['largest_stress_box']} (middle "
                        f"{m['middle_stress_box_largest']}), expected {largest}")
    hold = rep["hold"]["stress_zz_kPa"]
    if not math.isclose(hold["stressB"], 700.0, rel_tol=1e-9) or hold["stressC"] != 30.0:
        fail.append(f"stress boxes in the hold 0.3-0.4 s: {hold}, expected B 700, C 30 kPa")
    depths = [b["depth_m"] for b in rep["stress_boxes"]]
    if any(not math.isclose(z, BED_TOP - 0.4, rel_tol=1e-12) for z in depths):
        fail.append(f"stress boxes' depths {depths}, expected {BED_TOP - 0.4}")
    if "largest stressB (the middle box)" not in text:
        fail.append("the text report lacks the stress boxes: " + text[-600:])
with tempfile.TemporaryDirectory() as d:
    write_output(d, 5e-3, 0.15)
    rep, _ = run_report(d)
    fail += check_levels(rep, [0.105, 0.12, 0.135], "sampled every 5 ms, to 0.15 s")
    samples = [(min(m["cell_samples"].values()), m.get("nearest_sample_s"))
               for m in rep["load_levels"]]
    if len(samples) != 3 or samples[2] != (1, None) or any(
            n != 0 or not math.isclose(ts, want, rel_tol=1e-12)
            for (n, ts), want in zip(samples[:2], (0.105, 0.12))):
        fail.append(f"5 ms: the nearest samples 0.105 and 0.12 s, then one in the window "
                    f"expected: {samples}")
if fail:
    print("\n".join(fail))
    sys.exit(1)
print("ok")
