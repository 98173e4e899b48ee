#!/usr/bin/python3
"""Sleeper runs side by side at given moments: is a change (a DEM step, a seed, a control run
with a perturbed load) larger than the runs' chaos?

usage: tools/sleeper_compare.py RUN_DIR RUN_DIR... --at T[,T...] [--window H] [--from T0]
                                [--json FILE]

For each moment T, each run's figures averaged over [T - H, T + H] (the monitor's and the
sensors' samples in it; H = 0 or a window without samples: the sample nearest T), and the
difference of every run from the first:

  settlement_mm            mean uz of the sleeper's bottom probes (fem_monitor.csv b*_uz)
  under_load_mm            the same minus its value at T0 (--from: the load's start)
  interface_fz_kN          the rocks' vertical force on the sleeper (fem_monitor.csv force_z)
  strain_<gauge>_ue        each strain gauge's bottom-fibre axial strain, microstrain: the
                           monitor's probe pair sg_<gauge>_0/_1 of the run's scene (run.json),
                           (ux_1 - ux_0) over the distance of their mesh nodes, as
                           tools/sleeper_report.py measures it
  base_kN                  the rocks' vertical force on the box (sensor_base.csv, -fz)
  <cell>_kPa               each wall_force sensor named cell*: the top face's vertical
                           pressure, -fz over the face's area (force / pressure of its row),
                           as tools/sleeper_report.py reads it (thesis fig. 6.14)
  <packing>_Z, _phi        each packing sensor's coordination number and solid fraction
  kinetic_energy_J         sensor_kinetic_energy.csv
  max_principal_strain_ue  the FEM's largest principal strain (fem_series.csv), microstrain

The coordination, solid fraction, kinetic energy and strain are taken at the sample nearest
T (they are written every 0.01-0.02 s). Then, for every run after the first: the largest
difference of its settlement curve from the first run's over the times both wrote, and up to
when. A moment after a run's end is refused (exit 2), naming the run.

Example (docs/cases.md, "Choosing the DEM time step (sleeper)": the full bed at 2e-6 and 5e-6 s
and a control at 5e-6 s with the seating load changed by 1e-9):

    tools/sleeper_compare.py out/sleeper_tiled out/sleeper_tiled_dt5e-6 \\
        out/sleeper_tiled_dt5e-6_ctl --at 0.26,0.38 --window 0.006 --from 0.2
"""

import argparse
import json
import os
import re
import sys

import demfem_post
import sleeper_report
from demfem_post import read_csv, tool_errors

TOOL = "sleeper_compare.py"


class RunSeries:
    """The series of one run folder that the comparison reads (pure Python lists)."""

    def __init__(self, path):
        self.path = path
        mon = read_csv(os.path.join(path, "fem_monitor.csv"))
        self.t = list(mon.column("time"))
        probes = [h for h in mon if re.match(r"b\w+_uz$", h)]
        if not probes:
            raise ValueError(f"{path}/fem_monitor.csv: no bottom probes b*_uz")
        cols = [list(mon.column(p)) for p in probes]
        self.settle = [1e3 * sum(c[i] for c in cols) / len(cols) for i in range(len(self.t))]
        self.fz = list(mon.column("force_z")) if "force_z" in mon else None
        self.gauges = gauge_strains(path, mon)
        self.sensors = {}
        for name in sorted(os.listdir(path)):
            m = re.match(r"sensor_(\w+)\.csv$", name)
            if m:
                self.sensors[m.group(1)] = read_csv(os.path.join(path, name))
        fs = os.path.join(path, "fem_series.csv")
        self.fem_series = read_csv(fs) if os.path.exists(fs) else None

    def end(self):
        return self.t[-1]


def gauge_strains(path, mon):
    """{label: bottom-fibre axial strain per monitor row} of the strain gauges sg_<label>_0/_1
    of the run's scene (run.json), as tools/sleeper_report.py measures them: (ux_1 - ux_0) over
    the x distance of the mesh nodes nearest to the two probes. Empty when the run records no
    scene, or the scene no gauge or no mesh file."""
    try:
        run = demfem_post.open(path)
        scene = run.scene()
        mesh = os.path.join(os.path.dirname(os.path.abspath(run.info["scene"])),
                            scene["fem"]["mesh"]["file"])
        gauges = sleeper_report.strain_gauges(scene, sleeper_report.inp_nodes(mesh))
    except (OSError, KeyError, ValueError):
        return {}
    return {label: [(b - a) / (x1 - x0) for a, b in zip(mon.column(p0 + "_ux"),
                                                         mon.column(p1 + "_ux"))]
            for label, (x0, x1, p0, p1) in gauges.items()
            if p0 + "_ux" in mon and p1 + "_ux" in mon}


def mean_at(t, v, tm, half):
    """Mean of v over [tm - half, tm + half], or the sample nearest tm if none lies in it."""
    sel = [x for s, x in zip(t, v) if tm - half - 1e-12 <= s <= tm + half + 1e-12]
    if sel:
        return sum(sel) / len(sel)
    return nearest(t, v, tm)


def nearest(t, v, tm):
    i = min(range(len(t)), key=lambda j: abs(t[j] - tm))
    return v[i]


def figures(run, tm, half, t_from):
    f = {"settlement_mm": mean_at(run.t, run.settle, tm, half)}
    if t_from is not None:
        f["under_load_mm"] = f["settlement_mm"] - mean_at(run.t, run.settle, t_from, half)
    if run.fz is not None:
        f["interface_fz_kN"] = mean_at(run.t, run.fz, tm, half) / 1e3
    for label, e in run.gauges.items():
        f[f"strain_{label}_ue"] = 1e6 * mean_at(run.t, e, tm, half)
    for name, s in run.sensors.items():
        t = list(s.column("time"))
        if name == "base" and "fz" in s:
            f["base_kN"] = -mean_at(t, list(s.column("fz")), tm, half) / 1e3
        elif name.startswith("cell") and "pressure" in s:
            fz, force, p = s.column("fz"), s.column("force"), s.column("pressure")
            area = next((a / b for a, b in zip(force, p) if b > 0), None)
            if area:
                f[name + "_kPa"] = -mean_at(t, [x / area / 1e3 for x in fz], tm, half)
        elif "coordination" in s and "solid_fraction" in s:
            f[name + "_Z"] = nearest(t, list(s.column("coordination")), tm)
            f[name + "_phi"] = nearest(t, list(s.column("solid_fraction")), tm)
        elif "kinetic_energy" in s:
            f["kinetic_energy_J"] = nearest(t, list(s.column("kinetic_energy")), tm)
    if run.fem_series is not None and "max_principal_strain" in run.fem_series:
        f["max_principal_strain_ue"] = 1e6 * nearest(
            list(run.fem_series.column("time")), list(run.fem_series.column("max_principal_strain")),
            tm)
    return f


def curve_difference(a, b):
    """(largest |settlement difference| in mm over the monitor times both runs wrote, the last
    such time), or (None, None)."""
    ta = {round(t, 9): s for t, s in zip(a.t, a.settle)}
    common = [(round(t, 9), s) for t, s in zip(b.t, b.settle) if round(t, 9) in ta]
    if not common:
        return None, None
    return max(abs(s - ta[t]) for t, s in common), common[-1][0]


def parse(argv):
    ap = argparse.ArgumentParser(description="sleeper runs side by side at given moments")
    ap.add_argument("runs", nargs="+", metavar="RUN_DIR")
    ap.add_argument("--at", required=True, help="moments, s, comma-separated")
    ap.add_argument("--window", type=float, default=0.0, help="half-width H of the mean, s")
    ap.add_argument("--from", dest="t_from", type=float, default=None,
                    help="T0, s: under_load_mm counts the settlement from it")
    ap.add_argument("--json", default=None, help="write the figures as JSON to this file")
    a = ap.parse_args(argv)
    try:
        a.times = [float(x) for x in a.at.split(",")]
    except ValueError:
        ap.error(f"--at {a.at!r}: expected seconds separated by commas, e.g. 0.26,0.38")
    if len(a.runs) < 2:
        ap.error("give at least two run folders")
    if a.window < 0:
        ap.error("--window must be >= 0 s")
    return a


def main(argv):
    a = parse(argv)
    runs = [RunSeries(p) for p in a.runs]
    for r in runs:
        late = [t for t in a.times + ([a.t_from] if a.t_from is not None else []) if t > r.end() + 1e-9]
        if late:
            raise ValueError(f"{r.path}: its monitor ends at t = {r.end():g} s, before "
                             f"{', '.join(f'{t:g}' for t in late)} s")
    names = [os.path.basename(os.path.normpath(p)) for p in a.runs]
    out = {"runs": a.runs, "window_s": a.window, "from_s": a.t_from, "moments": []}
    for tm in a.times:
        figs = [figures(r, tm, a.window, a.t_from) for r in runs]
        keys = [k for k in figs[0] if all(k in f for f in figs)]
        print(f"t = {tm:g} s (mean over +-{a.window:g} s)")
        head = ["quantity"] + names + [f"{n} - {names[0]}" for n in names[1:]]
        rows = [[k] + [f"{f[k]:.4g}" for f in figs] + [f"{f[k] - figs[0][k]:+.3g}" for f in figs[1:]]
                for k in keys]
        widths = [max(len(r[c]) for r in rows + [head]) for c in range(len(head))]
        for r in [head] + rows:
            print("  ".join(x.rjust(w) if c else x.ljust(w) for c, (x, w) in enumerate(zip(r, widths))))
        out["moments"].append({"time": tm, "figures": dict(zip(a.runs, figs))})
    out["settlement_curve"] = []
    for p, r in zip(a.runs[1:], runs[1:]):
        d, until = curve_difference(runs[0], r)
        out["settlement_curve"].append({"run": p, "largest_difference_mm": d, "until_s": until})
        if d is not None:
            print(f"settlement curve of {p} against {a.runs[0]}: largest difference {d:.3g} mm "
                  f"(to t = {until:g} s)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    with tool_errors(TOOL):
        sys.exit(main(sys.argv[1:]))
