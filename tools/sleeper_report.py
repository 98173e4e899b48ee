#!/usr/bin/python3
"""Plots and key figures of a sleeper-on-ballast run (thesis ch. 6, cases/sleeper*.toml).

usage: tools/sleeper_report.py OUTPUT_DIR --scene SCENE [--hold T0,T1 | last:D] [--rock-density RHO]
                               [--set KEY=VALUE ...] [--beside OTHER_OUTPUT_DIR ...]

Reads, from OUTPUT_DIR: fem_monitor.csv (bottom probes b*_uz of the sleeper), sensor_base.csv
(force of the rocks on the box: its fz is minus the base reaction), sensor_cell<k>.csv (force
of the rocks on pressure cell k), sensor_all_rocks.csv (a packing sensor over the whole box:
the rocks' volume) and the packing sensors sensor_packing_*.csv / sensor_under_sleeper.csv
when there, and the stress boxes: packing sensors named stress* with `contacts = true`, whose
stress_zz (Love-Weber, compression positive) is the vertical Cauchy stress of the rocks'
contacts in the box, as Song et al. read pressure in their simulation (thesis §6.5): the
report gives it beside the cells at each load level and in the hold, and draws it (dotted,
open markers) in cell_pressures_levels.png; and from SCENE (the load case's TOML): the load
pattern (start, ramp, cycles, time scale, levels and seats), the seating load, the sleeper's
density and the mesh (its volume from the node bounding box), the cells' density and size, and
the all_rocks box;
--set KEY=VALUE changes a key of SCENE as `demfem run --set` did for the run; the overrides
the run recorded in OUTPUT_DIR/run.json are applied first, so the report of a run with
--set (400 cycles instead of the scene's 100, say) needs none here.
Writes into OUTPUT_DIR:
  settlement.png       settlement (mean uz of the bottom probes, mm) against time (top axis:
                       the pattern's reference time, fig. 6.7's), and at each cycle's minimum
                       load against the cycle number
  cell_pressures.png   each cell's pressure (vertical force of the rocks / top area, kPa)
                       against time, and the five cells' pressures in the hold against x
  sleeper_strain.png   the sleeper's bending strain against time: the bottom fibre's axial
                       strain at each strain gauge (below), and the largest principal strain
                       of all elements (fem_series.csv, thesis fig. 6.8) when written
  cell_pressures_levels.png
                       thesis fig. 6.14: the five cells' pressures against x at the thesis's
                       load levels, 44 kN (triangles) and 132 kN (circles) per rail seat on
                       the ramp before the cycles (left) and on the ramp after them (right);
                       with --beside, the other runs' (their sleeper_report.json: the cells
                       0.26 m deep of cases/sleeper_cells026.toml beside the 0.13 m of
                       cases/sleeper.toml, say) in other colours, labelled by depth
  sleeper_report.txt   the key figures in words
  sleeper_report.json  the same, for scripts and tests
Force balance of the static hold (--hold window, the load held at its peak): the base
reaction (mean of -fz of the box over the window), plus the force holding the frozen rocks
when the run froze some (sensor_frozen.csv, [dem.freeze]), against the weights of the rocks
(all_rocks volume x density x g), the cells and the sleeper plus the applied load (seating
+ every seat's peak). Exit status 2 on a missing file, column or scene key.
Load levels (json "load_levels"): the thesis compares the cells at 44 and 132 kN of its 220 kN
peak on the linear ramps before and after the cycles (§6.5); a scene with another peak_force is
read at the same fractions of it (0.2 and 0.6: 11 and 33 kN at the CI's 55 kN). Each moment
comes from the pattern's keys (docs/scene_fem.md); so do the first and the last cycle's peaks
(cycle_max: 44 kN in the thesis; stages first_cycle and last_cycle, in the json and the text,
not in the figure); the pressures there are the mean of each
cell's samples within +-2 % of the ramp's duration about it (the load within +-2 % of the peak,
symmetric, so the mean load is the level), or the sample nearest it when that window holds
none; with the settlement then, the largest cell and whether it is the middle one (x). Moments
after the run's end are left out. json "cells": each cell's top and its depth under the bed's
top (under_sleeper's highest rock at t = 0), the tops from the first walls snapshot when
readable, else from the scene.
Strain gauges: a pair of monitor probes named sg_<label>_0 and sg_<label>_1 (two nodes of
the bottom face on the centre line, 0 at the smaller x) is a gauge of length x_1 - x_0 (of
the mesh nodes nearest to the probe points); its strain is (ux_1 - ux_0) / (x_1 - x_0), the
mean axial strain of the bottom fibre between them (positive: tension, sagging).
"""

import argparse
import json
import math
import os
import re
import sys
import types
import tomllib

import demfem_post
from demfem_post import MissingModule, load_scene, read_csv, run_overrides
from demfem_post.plots import pyplot_or_exit

G = 9.81


def window_text(w):
    """[t0, t1] s, without the round-off of a window taken from a series' last time."""
    return f"[{w[0]:.6g}, {w[1]:.6g}] s"


def window_mean(t, y, t0, t1):
    v = [b for a, b in zip(t, y) if t0 - 1e-9 <= a <= t1 + 1e-9]  # times are sums of steps
    return (sum(v) / len(v)) if v else None


def inp_nodes(path):
    """The nodes of the *NODE blocks of an Abaqus deck, as [x, y, z] lists."""
    nodes = []
    in_nodes = False
    with open(path) as f:
        for line in f:
            s = line.strip()
            if s.startswith("*"):
                in_nodes = s.upper().split(",")[0].strip() == "*NODE"
                continue
            if in_nodes and s:
                nodes.append([float(x) for x in s.split(",")[1:4]])
    return nodes


def bounding_box(nodes):
    """(lo, hi) of the nodes (the sleeper is a box)."""
    return ([min(n[k] for n in nodes) for k in range(3)],
            [max(n[k] for n in nodes) for k in range(3)])


def strain_gauges(sc, mesh_nodes):
    """{label: (x_0, x_1, probe_0, probe_1)} of the sg_<label>_0/1 probe pairs of the scene,
    x of the mesh nodes nearest to the probe points (the monitor measures there)."""
    probes = {p["name"]: p["point"] for p in sc["fem"].get("monitor", {}).get("probes", [])}
    gauges = {}
    for name in probes:
        m = re.fullmatch(r"sg_(\w+)_0", name)
        if not m or f"sg_{m.group(1)}_1" not in probes:
            continue
        xs = []
        for k in (0, 1):
            pt = probes[f"sg_{m.group(1)}_{k}"]
            xs.append(min(mesh_nodes, key=lambda n: sum((a - b) ** 2 for a, b in zip(n, pt)))[0])
        if xs[1] <= xs[0]:
            raise ValueError(f"strain gauge sg_{m.group(1)}: probe _1 must lie at a larger x "
                             "than probe _0 (on another mesh node)")
        gauges[m.group(1)] = (xs[0], xs[1], f"sg_{m.group(1)}_0", f"sg_{m.group(1)}_1")
    return gauges


def scene_figures(scene_path, rock_density, overrides=()):
    """What the balance and the cycle marks need, read from the load case's scene."""
    sc = load_scene(scene_path, overrides)
    folder = os.path.dirname(os.path.abspath(scene_path))
    fem, dem = sc["fem"], sc["dem"]
    mats = {m["name"]: m for m in fem["materials"]}
    sleeper_density = mats[fem["sections"][0]["material"]]["density"]
    mesh_nodes = inp_nodes(os.path.join(folder, fem["mesh"]["file"]))
    lo, hi = bounding_box(mesh_nodes)
    sleeper_volume = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2])
    seating, seats, pattern = 0.0, 0, None
    for p in fem.get("pressures", []):
        amp = p.get("amplitude")
        if isinstance(amp, dict) and amp.get("type") == "sleeper":
            pattern = amp
            per = p.get("total_force", 0.0)
            if amp.get("force_is", "per_seat") == "total":
                per /= amp.get("seats", 2)
            seats += per
        elif amp is None:
            seating += p.get("total_force", 0.0)
    if pattern is None:
        raise KeyError(f"{scene_path}: no [[fem.pressures]] with amplitude type \"sleeper\"")
    peak = pattern.get("peak_force", 220e3) * seats
    dmat = {m["name"]: m for m in dem["materials"]}
    rho = rock_density if rock_density else dmat["granite"]["density"]
    cells = []
    for w in dem.get("walls", []):
        if "body" in w and w["name"].startswith("cell"):
            b = w["box"]
            v = 1.0
            for k in range(3):
                v *= b["hi"][k] - b["lo"][k]
            cells.append({"name": w["name"], "x": 0.5 * (b["lo"][0] + b["hi"][0]),
                          "mass": w["body"]["density"] * v, "top": b["hi"][2],
                          "area": (b["hi"][0] - b["lo"][0]) * (b["hi"][1] - b["lo"][1])})
    # Cauchy-stress boxes (Song et al.'s method, thesis §6.5): packing sensors named stress*
    # with the contact statistics, their stress_zz the Love-Weber stress of the box
    stress_boxes = [{"name": s["name"], "x": 0.5 * (s["lo"][0] + s["hi"][0]),
                     "z_lo": s["lo"][2], "z_hi": s["hi"][2]}
                    for s in dem.get("sensors", []) if s.get("kind") == "packing"
                    and s["name"].startswith("stress") and s.get("contacts", False)]
    rocks_box = None
    for s in dem.get("sensors", []):
        if s["name"] == "all_rocks":
            rocks_box = 1.0
            for k in range(3):
                rocks_box *= s["hi"][k] - s["lo"][k]
    return {"sleeper_mass": sleeper_density * sleeper_volume, "seating_N": seating,
            "peak_load_N": peak, "pattern": pattern, "rock_density": rho, "cells": cells,
            "stress_boxes": stress_boxes, "rocks_box_volume": rocks_box,
            "gauges": strain_gauges(sc, mesh_nodes)}


def read_run(out, fig):
    """The run's series the report needs (monitor, FEM series, sensors) as a namespace."""
    d = types.SimpleNamespace()
    mon_path = os.path.join(out, "fem_monitor.csv")
    mon = read_csv(mon_path)
    d.t = t = mon.column("time")
    d.probes = sorted({m.group(1) for h in mon for m in [re.match(r"(b\w+)_uz$", h)] if m})
    if not d.probes:
        raise KeyError(f"{mon_path}: no bottom probes b*_uz")
    d.uz = uz = [mon.column(p + "_uz") for p in d.probes]
    d.strain = {}  # label -> bottom-fibre axial strain per monitor row
    for label, (x0, x1, p0, p1) in fig["gauges"].items():
        u0, u1 = mon.column(p0 + "_ux"), mon.column(p1 + "_ux")
        d.strain[label] = [(b - c) / (x1 - x0) for b, c in zip(u1, u0)]
    series_path = os.path.join(out, "fem_series.csv")
    d.max_strain = None
    if os.path.exists(series_path):
        rows = read_csv(series_path)
        if "max_principal_strain" in rows:
            d.max_strain = (rows.column("time"), rows.column("max_principal_strain"))
    d.settle = [1e3 * sum(u[i] for u in uz) / len(uz) for i in range(len(t))]  # mm
    d.tilt = [1e3 * (uz[-1][i] - uz[0][i]) for i in range(len(t))]  # last - first probe, mm
    d.cells = []
    for c in fig["cells"]:
        rows = read_csv(os.path.join(out, f"sensor_{c['name']}.csv"))
        # the rocks push the cell down: -fz is the vertical load on it
        d.cells.append((c, rows.column("time"),
                        [-f / c["area"] / 1e3 for f in rows.column("fz")]))
    d.stress = []  # (box, time, vertical stress kPa, compression positive)
    for b in fig["stress_boxes"]:
        rows = read_csv(os.path.join(out, f"sensor_{b['name']}.csv"))
        d.stress.append((b, rows.column("time"), [v / 1e3 for v in rows.column("stress_zz")]))
    base = read_csv(os.path.join(out, "sensor_base.csv"))
    d.tb, d.fb = base.column("time"), base.column("fz")
    # rocks frozen by [dem.freeze] are held by the engine, not the box: the force that
    # holds them (sensor kind "frozen", fz upwards) carries its share
    frozen_path = os.path.join(out, "sensor_frozen.csv")
    d.tf = d.ff = None
    if os.path.exists(frozen_path):
        rows = read_csv(frozen_path)
        d.tf, d.ff = rows.column("time"), rows.column("fz")
    d.packing = {}
    for name in ("all_rocks", "packing_lower", "packing_upper", "under_sleeper"):
        path = os.path.join(out, f"sensor_{name}.csv")
        if os.path.exists(path):
            rows = read_csv(path)
            d.packing[name] = {k: rows.column(k) for k in
                               ("time", "particles", "solid_fraction", "coordination", "top")}
    return d


def cycle_minima(fig, d):
    """Settlement at the cycles' minima (load at cycle_min), reference times T_r + k / f;
    returns [(cycle, settlement)], the index of the load's start and its time."""
    t, settle = d.t, d.settle
    pat = fig["pattern"]
    ts = pat.get("time_scale", 1.0)
    t0 = pat.get("start_time", 0.0)
    # the cycles begin after the first ramp and the unloading from the peak (if it takes time)
    c0 = pat.get("ramp_duration", 0.03) + pat.get("unload_duration", 0.0)
    freq = pat.get("cycle_frequency", 100.0)
    ncyc = pat.get("cycles", round(pat.get("cycle_duration", 0.06) * freq))
    cyc = []
    for k in range(int(ncyc) + 1):
        tk = t0 + ts * (c0 + k / freq)
        if tk > t[-1] + 1e-9:
            break
        i = min(range(len(t)), key=lambda j: abs(t[j] - tk))
        cyc.append((k, settle[i]))
    i_seat = min(range(len(t)), key=lambda j: abs(t[j] - t0))
    return cyc, i_seat, t0


def hold_figures(fig, d, hold_arg, i_seat):
    """The static hold's window means: settlement, force balance, cells, strain."""
    t, settle, packing = d.t, d.settle, d.packing
    if hold_arg.startswith("last:"):
        h1 = t[-1]
        h0 = h1 - float(hold_arg[5:])
    else:
        h0, h1 = (float(x) for x in hold_arg.split(","))
    hold = {"window": [h0, h1]}
    held_settle = window_mean(t, settle, h0, h1)
    if held_settle is not None:
        # the settlement under the load alone: counted from the seated sleeper (the load's
        # start), without the seating, whose size the prepared bed's top decides
        hold["held_settlement_mm"] = held_settle
        hold["held_settlement_under_load_mm"] = held_settle - settle[i_seat]
    tb, fb, tf, ff = d.tb, d.fb, d.tf, d.ff
    base_hold = window_mean(tb, fb, h0, h1)
    if base_hold is not None and "all_rocks" in packing and fig["rocks_box_volume"]:
        ar = packing["all_rocks"]
        rocks_v = window_mean(ar["time"], ar["solid_fraction"], h0, h1) * fig["rocks_box_volume"]
        w_rocks = rocks_v * fig["rock_density"] * G
        w_cells = sum(c["mass"] for c in fig["cells"]) * G
        w_sleeper = fig["sleeper_mass"] * G
        load = fig["seating_N"] + fig["peak_load_N"]
        expected = w_rocks + w_cells + w_sleeper + load
        held = (window_mean(tf, ff, h0, h1) or 0.0) if tf is not None else 0.0
        if tf is not None:
            hold["frozen_support_N"] = held
        hold.update({
            "base_reaction_N": -base_hold, "rocks_weight_N": w_rocks,
            "cells_weight_N": w_cells, "sleeper_weight_N": w_sleeper, "load_N": load,
            "expected_N": expected,
            "balance_rel": (-base_hold + held - expected) / expected,
            "base_reaction_sd_N": math.sqrt(max(0.0, window_mean(
                tb, [f * f for f in fb], h0, h1) - base_hold ** 2)),
        })
    hold["cell_pressure_kPa"] = {c["name"]: window_mean(tc, p, h0, h1) for c, tc, p in d.cells}
    if d.stress:
        hold["stress_zz_kPa"] = {b["name"]: window_mean(tb, v, h0, h1) for b, tb, v in d.stress}
    read = [(p, c) for (c, _, _), p in zip(d.cells, hold["cell_pressure_kPa"].values())
            if p is not None]
    if read:  # the question: is the pressure largest under a rail seat or the centre?
        p, c = max(read, key=lambda pc: pc[0])
        hold["largest_cell"] = {"name": c["name"], "x": c["x"], "pressure_kPa": p}
    if d.strain:
        hold["strain"] = {label: window_mean(t, e, h0, h1) for label, e in d.strain.items()}
    return hold


def first_loaded_rows(packing):
    # a loaded state has no contact forces before its first step: the packing's first row
    # is the first one after it
    return {name: next((i for i, x in enumerate(p["time"]) if x > 0), 0)
            for name, p in packing.items()}


# The thesis's comparison with Song et al. (§6.5, fig. 6.14): the cells' pressures at 44 and
# 132 kN per rail seat on the linear ramps before and after the cycles, of the pattern's
# 220 kN peak. A scene with another peak (the CI load scale 0.25: 55 kN) is read at the same
# fractions of its own peak, so that its levels stand where the thesis's stand in the pattern.
THESIS_PEAK_N = 220e3
THESIS_LEVELS_N = (44e3, 132e3)
# half-width of the window the pressures are averaged over, as a fraction of the ramp's
# duration: the load varies by +-2 % of the peak in it (+-4.4 kN at 220 kN), symmetric about
# the moment, so that its mean load is the level
LEVEL_WINDOW_OF_RAMP = 0.02


def pattern_times(pat):
    """(start, time scale, ramp, first ramp's end + unloading T_1, cycles' end T_2) of the
    sleeper pattern (docs/scene_fem.md), reference times in s."""
    freq = pat.get("cycle_frequency", 100.0)
    ramp = pat.get("ramp_duration", 0.03)
    t1 = ramp + pat.get("unload_duration", 0.0)
    cycles = (pat["cycles"] / freq) if "cycles" in pat else pat.get("cycle_duration", 0.06)
    return pat.get("start_time", 0.0), pat.get("time_scale", 1.0), ramp, t1, t1 + cycles


STAGE_WORDS = {"before": "on the ramp before the cycles", "first_cycle": "at the first cycle's "
               "peak", "last_cycle": "at the last cycle's peak", "after": "on the ramp after "
               "the cycles"}


def level_moments(pat):
    """The moments the pattern passes the thesis's levels on its two ramps, and the first and
    the last cycle's peaks (cycle_max, 44 kN in the thesis), in time order: [{level_kN (the
    thesis's), stage (STAGE_WORDS), load_per_seat_N (the scene's), time}]."""
    start, scale, ramp, t1, t2 = pattern_times(pat)
    peak = pat.get("peak_force", THESIS_PEAK_N)
    moments = []
    for stage, ramp_start in (("before", 0.0), ("after", t2)):
        for level in THESIS_LEVELS_N:
            fraction = level / THESIS_PEAK_N
            moments.append({"level_kN": level / 1e3, "stage": stage,
                            "load_per_seat_N": fraction * peak,
                            "time": start + scale * (ramp_start + fraction * ramp)})
    freq = pat.get("cycle_frequency", 100.0)
    cycle_max = pat.get("cycle_max", 44e3)
    for stage, k in (("first_cycle", 0), ("last_cycle", round((t2 - t1) * freq) - 1)):
        # F = cycle_min + (cycle_max - cycle_min) (1 - cos 2 pi f (tau - T_1)) / 2: the peak
        # of cycle k at tau = T_1 + (k + 1/2) / f
        moments.append({"level_kN": round(cycle_max / peak * THESIS_PEAK_N / 1e3, 9) if peak
                        else cycle_max / 1e3, "stage": stage, "load_per_seat_N": cycle_max,
                        "time": start + scale * (t1 + (k + 0.5) / freq)})
    return sorted(moments, key=lambda m: m["time"])


def value_at(t, y, tm, half):
    """(mean of y over [tm - half, tm + half], the number of samples in it, None); the sample
    nearest tm, 0 and its time when the window holds none (a series sampled more coarsely)."""
    v = window_mean(t, y, tm - half, tm + half)
    if v is not None:
        return v, sum(1 for a in t if tm - half - 1e-9 <= a <= tm + half + 1e-9), None
    i = min(range(len(t)), key=lambda j: abs(t[j] - tm))
    return y[i], 0, t[i]


def middle_cell(cells):
    """The name of the middle cell by x (the one under the sleeper's centre)."""
    by_x = sorted(cells, key=lambda c: c["x"])
    return by_x[len(by_x) // 2]["name"]


def level_figures(fig, d):
    """The cells' pressures, the settlement and the largest cell at each level moment that
    the run reached (fig. 6.14); moments after the run's end are left out."""
    _, scale, ramp, _, _ = pattern_times(fig["pattern"])
    half = LEVEL_WINDOW_OF_RAMP * scale * ramp
    middle = middle_cell(fig["cells"])
    middle_box = middle_cell(fig["stress_boxes"]) if d.stress else None
    levels = []
    for m in level_moments(fig["pattern"]):
        tm = m["time"]
        if not d.cells or tm > min(tc[-1] for _, tc, _ in d.cells) + 1e-9:
            continue
        entry = dict(m, window=[tm - half, tm + half], cell_pressure_kPa={}, cell_samples={})
        for c, tc, p in d.cells:
            v, n, nearest = value_at(tc, p, tm, half)
            entry["cell_pressure_kPa"][c["name"]], entry["cell_samples"][c["name"]] = v, n
            if nearest is not None:
                entry["nearest_sample_s"] = nearest
        entry["settlement_mm"] = value_at(d.t, d.settle, tm, half)[0]
        name = max(entry["cell_pressure_kPa"], key=entry["cell_pressure_kPa"].get)
        entry["largest_cell"] = name
        entry["middle_cell_largest"] = name == middle
        if d.stress:
            entry["stress_zz_kPa"] = {b["name"]: value_at(tb, v, tm, half)[0]
                                      for b, tb, v in d.stress}
            name = max(entry["stress_zz_kPa"], key=entry["stress_zz_kPa"].get)
            entry["largest_stress_box"] = name
            entry["middle_stress_box_largest"] = name == middle_box
        levels.append(entry)
    return levels


def cell_depths(out, fig, d):
    """[{name, x, area_m2, top_m, depth_m}]: each cell's top and its depth under the bed's top (the
    under_sleeper sensor's highest rock at t = 0, before the sleeper) in the run's first
    walls snapshot (the cells' pose as prepared); the scene's box when the walls or that
    sensor are not written or not readable (no numpy / libhdf5)."""
    tops = {c["name"]: c["top"] for c in fig["cells"]}
    source = "scene"
    try:
        walls = demfem_post.open(out).walls(0.0)
        tops = {n: float(walls[n].points[:, 2].max()) for n in tops}
        source = "walls output, first snapshot"
    except (FileNotFoundError, KeyError, ValueError, OSError, MissingModule):
        pass
    under = d.packing.get("under_sleeper")
    bed_top = under["top"][0] if under else None
    return source, bed_top, [{"name": c["name"], "x": c["x"], "area_m2": c["area"],
                              "top_m": tops[c["name"]],
                              "depth_m": (bed_top - tops[c["name"]]) if bed_top else None}
                             for c in fig["cells"]]


def report_of(fig, d, cyc, i_seat, hold_arg):
    t, settle, tilt = d.t, d.settle, d.tilt
    report = {"probes": d.probes, "final_time": t[-1], "settlement_final_mm": settle[-1],
              "settlement_min_mm": min(settle), "settlement_at_load_start_mm": settle[i_seat],
              "tilt_at_load_start_mm": tilt[i_seat], "tilt_final_mm": tilt[-1],
              "cycles": [{"cycle": k, "settlement_mm": s} for k, s in cyc],
              "sleeper_mass_kg": fig["sleeper_mass"], "applied_load_N":
              fig["seating_N"] + fig["peak_load_N"]}
    if d.strain:
        report["strain"] = {}
        for label, (x0, x1, _, _) in fig["gauges"].items():
            e = d.strain[label]
            report["strain"][label] = {"x0": x0, "x1": x1, "max": max(e), "min": min(e),
                                       "final": e[-1]}
    if d.max_strain is not None:
        report["max_principal_strain"] = max(d.max_strain[1])
    first = first_loaded_rows(d.packing)
    for name, p in d.packing.items():
        report["packing_" + name if not name.startswith("packing") else name] = {
            "first": {k: v[first[name]] for k, v in p.items()},
            "last": {k: v[-1] for k, v in p.items()}}
    if hold_arg:
        report["hold"] = hold_figures(fig, d, hold_arg, i_seat)
    report["load_levels"] = level_figures(fig, d)
    return report


def report_lines(out, d, report, cyc, i_seat):
    t, settle, tilt = d.t, d.settle, d.tilt
    lines = [f"sleeper run {out}: {len(t)} monitor rows up to t = {t[-1]:.4f} s",
             f"settlement (mean uz of {len(d.probes)} bottom probes): at the load start "
             f"{settle[i_seat]:.3f} mm, final {settle[-1]:.3f} mm, lowest {min(settle):.3f} mm; "
             f"tilt (last - first probe) {tilt[i_seat]:.3f} mm at the load start, "
             f"{tilt[-1]:.3f} mm at the end"]
    if cyc:
        lines.append("settlement at the cycle minima: " +
                     ", ".join(f"{k}: {s:.3f}" for k, s in cyc) + " mm")
    for label, g in report.get("strain", {}).items():
        lines.append(f"bottom-fibre strain {label} (x {g['x0']:.4f}-{g['x1']:.4f} m): "
                     f"max {1e6 * g['max']:.1f}, min {1e6 * g['min']:.1f}, final "
                     f"{1e6 * g['final']:.1f} microstrain")
    if "max_principal_strain" in report:
        lines.append(f"largest principal strain of all elements: "
                     f"{1e6 * report['max_principal_strain']:.1f} microstrain")
    first = first_loaded_rows(d.packing)
    for name, p in d.packing.items():
        i = first[name]
        lines.append(f"{name} (t = {p['time'][i]:.4f} -> {p['time'][-1]:.4f} s): solid fraction "
                     f"{p['solid_fraction'][i]:.4f} -> {p['solid_fraction'][-1]:.4f}, "
                     f"coordination {p['coordination'][i]:.3f} -> {p['coordination'][-1]:.3f}, "
                     f"{p['particles'][i]:.0f} rocks, top {p['top'][0]:.4f} (t = 0) -> "
                     f"{p['top'][-1]:.4f} m")
    if "hold" in report:
        lines += hold_lines(report["hold"])
    return lines


def hold_lines(h):
    lines = []
    if "held_settlement_mm" in h:
        lines.append(f"settlement in the hold {window_text(h['window'])}: "
                     f"{h['held_settlement_mm']:.3f} mm, of it under the load (from the load "
                     f"start) {h['held_settlement_under_load_mm']:.3f} mm")
    if "base_reaction_N" in h:
        held = (f" + frozen rocks' support {h['frozen_support_N']:.1f} N"
                if "frozen_support_N" in h else "")
        lines.append(
            f"static hold {window_text(h['window'])}: base reaction {h['base_reaction_N']:.1f} N "
            f"(sd {h['base_reaction_sd_N']:.1f}){held} against rocks {h['rocks_weight_N']:.1f} + "
            f"cells {h['cells_weight_N']:.1f} + sleeper {h['sleeper_weight_N']:.1f} + load "
            f"{h['load_N']:.1f} = {h['expected_N']:.1f} N: {100 * h['balance_rel']:+.3f} %")
    lines.append("cell pressures in the hold (kPa): " + ", ".join(
        f"{n} {p:.2f}" if p is not None else f"{n} -"
        for n, p in h["cell_pressure_kPa"].items()))
    if "stress_zz_kPa" in h:
        lines.append("stress boxes' vertical stress in the hold (kPa): " + ", ".join(
            f"{n} {p:.2f}" if p is not None else f"{n} -"
            for n, p in h["stress_zz_kPa"].items()))
    if "largest_cell" in h:
        c = h["largest_cell"]
        lines.append(f"largest cell pressure in the hold: {c['name']} at x = {c['x']:.4f} m "
                     f"({c['pressure_kPa']:.2f} kPa)")
    return lines


def level_lines(report):
    """The cells' depths and their pressures at the thesis's load levels, in words."""
    cells = report["cells"]
    lines = [f"pressure cells (tops from the {cells['source']}; bed top "
             + (f"{cells['bed_top_m']:.4f} m, under_sleeper at t = 0): " if cells["bed_top_m"]
                else "unknown: no under_sleeper sensor): ")
             + ", ".join(f"{c['name']} x {c['x']:.3f} top {c['top_m']:.4f} m"
                         + (f" depth {c['depth_m']:.3f} m" if c["depth_m"] is not None else "")
                         for c in cells["cells"])]
    if "stress_boxes" in report:
        lines.append("stress boxes (Cauchy stress of the rocks' contacts in a box, Song et al.'s "
                     "method): " + ", ".join(
                         f"{b['name']} x {b['x']:.3f} z {b['z_lo']:.3f}-{b['z_hi']:.3f} m"
                         + (f" centre depth {b['depth_m']:.3f} m" if b["depth_m"] is not None
                            else "") for b in report["stress_boxes"]))
    for m in report["load_levels"]:
        w = m["window"]
        pressures = ", ".join(f"{n} {p:.2f}" for n, p in m["cell_pressure_kPa"].items())
        n = min(m["cell_samples"].values())
        how = (f"mean of {n} sample{'s' if n > 1 else ''} in [{w[0]:.6g}, {w[1]:.6g}] s" if n else
               f"the sample nearest it, t = {m.get('nearest_sample_s', float('nan')):.6g} s, "
               f"none in [{w[0]:.6g}, {w[1]:.6g}] s")
        lines.append(
            f"{m['level_kN']:g} kN level {STAGE_WORDS[m['stage']]} (this scene's "
            f"{m['load_per_seat_N'] / 1e3:.4g} kN per seat at t = {m['time']:.6g} s; {how}): "
            f"cell pressures (kPa) {pressures}; largest {m['largest_cell']}"
            f"{' (the middle cell)' if m['middle_cell_largest'] else ' (not the middle cell)'}; "
            f"settlement {m['settlement_mm']:.3f} mm")
        if "stress_zz_kPa" in m:
            lines.append(
                "  stress boxes' vertical stress (kPa, Love-Weber) " + ", ".join(
                    f"{n} {p:.2f}" for n, p in m["stress_zz_kPa"].items())
                + f"; largest {m['largest_stress_box']}"
                + (" (the middle box)" if m["middle_stress_box_largest"] else
                   " (not the middle box)"))
    return lines


def depth_span(report, key="cells"):
    """The depths of the cells (key "cells") or of the stress boxes' centres ("stress_boxes")
    as words ('0.130' or '0.149-0.182'), None when unknown."""
    items = report["cells"]["cells"] if key == "cells" else report.get(key, [])
    depths = [c["depth_m"] for c in items if c["depth_m"] is not None]
    if not depths:
        return None
    lo, hi = f"{min(depths):.3f}", f"{max(depths):.3f}"
    return lo if lo == hi else f"{lo}-{hi}"


def beside_reports(folders):
    """[(folder, report)] of other runs' sleeper_report.json (--beside): their levels are drawn
    beside this run's (another depth of the cells, say). ValueError naming the file when one
    is missing or predates the levels."""
    runs = []
    for folder in folders:
        path = os.path.join(folder, "sleeper_report.json")
        try:
            with open(path) as f:
                other = json.load(f)
        except (OSError, json.JSONDecodeError) as e:
            raise ValueError(f"--beside {folder}: {path} is not readable ({e}); run "
                             "tools/sleeper_report.py on that run first") from None
        if "load_levels" not in other or "cells" not in other:
            raise ValueError(f"--beside {folder}: {path} has no load_levels / cells (written by "
                             "an older tools/sleeper_report.py): report that run again")
        runs.append((folder, other))
    return runs


def plot_levels(plt, out, report, beside=()):
    """cell_pressures_levels.png, as thesis fig. 6.14: the cells' pressures against their x,
    44 kN (triangles, dashed) and 132 kN (circles), before the cycles (left) and after
    (right); the runs of --beside in other colours, each labelled by its cells' depth."""
    f, ax = plt.subplots(1, 2, figsize=(11, 4.5 if beside else 4), sharey=True)
    runs = [(None, report)] + list(beside)
    for r, (folder, rep) in enumerate(runs):
        xs = {c["name"]: c["x"] for c in rep["cells"]["cells"]}
        who = f"{depth_span(rep) or '?'} m deep: " if beside else ""
        for k, stage in enumerate(("before", "after")):
            for m in (m for m in rep["load_levels"] if m["stage"] == stage):
                names = sorted(m["cell_pressure_kPa"], key=xs.get)
                ax[k].plot([xs[n] for n in names], [m["cell_pressure_kPa"][n] for n in names],
                           "^--" if m["level_kN"] < 100 else "o-", color=f"C{r % 10}",
                           label=f"{who}{m['level_kN']:g} kN (scene: "
                                 f"{m['load_per_seat_N'] / 1e3:.4g} kN per seat), "
                                 f"t = {m['time']:.4g} s")
                if "stress_zz_kPa" in m and rep.get("stress_boxes"):
                    bx = {b["name"]: b["x"] for b in rep["stress_boxes"]}
                    names = sorted(m["stress_zz_kPa"], key=bx.get)
                    depth = depth_span(rep, "stress_boxes")
                    ax[k].plot([bx[n] for n in names], [m["stress_zz_kPa"][n] for n in names],
                               "^:" if m["level_kN"] < 100 else "s:", color=f"C{r % 10}",
                               mfc="none", label=f"{who}{m['level_kN']:g} kN, Cauchy stress "
                                                 f"in boxes {depth or '?'} m deep")
    for k, stage in enumerate(("before", "after")):
        ax[k].set_title(f"{stage} the cycles")
        ax[k].set_xlabel("cell centre x (m)")
        ax[k].grid(True)
        if ax[k].lines:
            ax[k].legend(fontsize=7 if beside else 8)
        else:
            ax[k].text(0.5, 0.5, "not reached by the run", ha="center",
                       transform=ax[k].transAxes)
    span = depth_span(report)
    ax[0].set_ylabel(("cell pressure, box stress (kPa)" if report.get("stress_boxes")
                      else "cell pressure (kPa)")
                     + (f"\ncells' tops {span} m deep" if span and not beside else ""))
    f.tight_layout()
    f.savefig(os.path.join(out, "cell_pressures_levels.png"), dpi=110)


def plot_settlement(plt, out, d, cyc, t0, scale):
    t, uz, probes = d.t, d.uz, d.probes
    f1, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(t, d.settle, label="mean")
    ax[0].plot(t, [1e3 * v for v in uz[0]], lw=0.7, label=probes[0])
    ax[0].plot(t, [1e3 * v for v in uz[-1]], lw=0.7, label=probes[-1])
    ax[0].axvline(t0, color="grey", lw=0.5)
    # fig. 6.7's axis: the pattern's reference time (time scale 1), from the load's start
    ref = ax[0].secondary_xaxis("top", functions=(lambda x: (x - t0) / scale,
                                                  lambda r: t0 + r * scale))
    ref.set_xlabel(f"reference time of the pattern (s; time scale {scale:g}, fig. 6.7)",
                   fontsize=8)
    ax[0].set_xlabel("time (s)")
    ax[0].set_ylabel("settlement: uz of the bottom (mm)")
    ax[0].legend()
    ax[0].grid(True)
    if cyc:
        ax[1].plot([c[0] for c in cyc], [c[1] for c in cyc], "o-")
    ax[1].set_xlabel("cycle")
    ax[1].set_ylabel("settlement at the cycle minimum (mm)")
    ax[1].grid(True)
    f1.tight_layout()
    f1.savefig(os.path.join(out, "settlement.png"), dpi=110)


def plot_cells(plt, out, d, report):
    f2, ax = plt.subplots(1, 2, figsize=(11, 4))
    for c, tc, p in d.cells:
        ax[0].plot(tc, p, label=c["name"])
    ax[0].set_xlabel("time (s)")
    ax[0].set_ylabel("cell pressure: vertical force / top area (kPa)")
    ax[0].legend()
    ax[0].grid(True)
    if "hold" in report:
        xs = [c["x"] for c, _, _ in d.cells]
        ps = [report["hold"]["cell_pressure_kPa"][c["name"]] for c, _, _ in d.cells]
        ax[1].plot(xs, ps, "o-")
        ax[1].set_title(f"static hold {window_text(report['hold']['window'])}")
    ax[1].set_xlabel("cell centre x (m)")
    ax[1].set_ylabel("cell pressure (kPa)")
    ax[1].grid(True)
    f2.tight_layout()
    f2.savefig(os.path.join(out, "cell_pressures.png"), dpi=110)


def plot_strain(plt, out, fig, d, t0):
    if not d.strain and d.max_strain is None:
        return
    f3, ax = plt.subplots(figsize=(7, 4))
    for label, e in d.strain.items():
        x0, x1 = fig["gauges"][label][:2]
        ax.plot(d.t, [1e6 * v for v in e], lw=0.8,
                label=f"bottom fibre, x {x0:.3f}-{x1:.3f} m ({label})")
    if d.max_strain is not None:
        ax.plot(d.max_strain[0], [1e6 * v for v in d.max_strain[1]], "k.", ms=3,
                label="largest principal strain, all elements")
    ax.axvline(t0, color="grey", lw=0.5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("strain (microstrain; bottom fibre: + tension)")
    ax.legend(fontsize=8)
    ax.grid(True)
    f3.tight_layout()
    f3.savefig(os.path.join(out, "sleeper_strain.png"), dpi=110)


def main(argv):
    ap = argparse.ArgumentParser(description="sleeper run report")
    ap.add_argument("output")
    ap.add_argument("--scene", required=True, help="the load case's scene (TOML)")
    ap.add_argument("--hold", default=None,
                    help="T0,T1: window of the static hold, s; or last:D, the run's last D s "
                         "(runs of another length, e.g. a time-scale study's members)")
    ap.add_argument("--rock-density", type=float, default=None,
                    help="kg/m^3 (default: the scene's granite)")
    ap.add_argument("--beside", action="append", default=[], metavar="OUTPUT_DIR",
                    help="another sleeper run, already reported (its sleeper_report.json): "
                         "its cells' pressures at the load levels drawn beside this run's "
                         "(the cells 0.26 m deep beside 0.13 m, fig. 6.14)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a scene key as the run had it (demfem run --set)")
    a = ap.parse_args(argv)
    out = a.output
    try:
        fig = scene_figures(a.scene, a.rock_density, run_overrides(out) + a.set)
        d = read_run(out, fig)
        beside = beside_reports(a.beside)
    except (FileNotFoundError, KeyError, ValueError, tomllib.TOMLDecodeError) as e:
        print(f"sleeper_report.py: {e}", file=sys.stderr)
        return 2
    cyc, i_seat, t0 = cycle_minima(fig, d)
    report = report_of(fig, d, cyc, i_seat, a.hold)
    source, bed_top, cells = cell_depths(out, fig, d)
    report["cells"] = {"source": source, "bed_top_m": bed_top, "cells": cells}
    if fig["stress_boxes"]:
        report["stress_boxes"] = [dict(b, depth_m=(bed_top - 0.5 * (b["z_lo"] + b["z_hi"]))
                                       if bed_top else None) for b in fig["stress_boxes"]]
    report["load_start_s"] = t0  # the pattern's start: tools/sleeper_cutaway.py's reference
    if beside:
        report["beside"] = [{"output": folder, "cells_depth_m": depth_span(other)}
                            for folder, other in beside]
    with open(os.path.join(out, "sleeper_report.json"), "w") as f:
        json.dump(report, f, indent=1)
    lines = report_lines(out, d, report, cyc, i_seat) + level_lines(report)
    with open(os.path.join(out, "sleeper_report.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    plt = pyplot_or_exit("sleeper_report.py")
    plot_settlement(plt, out, d, cyc, t0, fig["pattern"].get("time_scale", 1.0))
    plot_cells(plt, out, d, report)
    plot_strain(plt, out, fig, d, t0)
    plot_levels(plt, out, report, beside)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
