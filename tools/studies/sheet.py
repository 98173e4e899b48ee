"""Stability and convergence studies of the steel-sheet case (docs/verification.md), as
sweeps of the base scene.

usage: python3 -m studies sheet stability   [--base cases/sheet_ci.toml] [--work DIR]
                                            [--bin DIR] [--end-time T]
       python3 -m studies sheet convergence [--base ...] [--work DIR] [--bin DIR]
                                            [--end-time T] [--window A,B] [--members LIST]
(tools/sheet_study.py STUDY ... is the same command.)

Each member is the base scene with some keys set (`--set`, through the sweep), run by the
sweep in WORK/<study>/members/<member>/; the prepare scene of the base (the CI fill) is made
once, in WORK/<study>/beds/, and shared ([execution] beds = "shared"). Members that are done
are not run again; a blown-up member is not retried. The table goes to stdout and
WORK/<study>.json.

stability: every scheme (just_in_time, predictive) with and without force averaging at
  dt_F = 1e-4, 2e-4, 5e-4 and 1e-3 s (dt_D fixed). A member is stable when the run ends
  (exit 0, no blow-up exit 3: the scene's bound coupling.blowup.max_overlap and the finite
  checks hold), the largest particle-sheet overlap stays below 10 % of the smallest grain
  radius, and the deflection at the probe stays within 0.1 m (a third of the sheet).
convergence: the base; dt_D halved; the shell mesh refined to 5 mm; the base on two threads
  (the CPU backend gives the same bits: a check, not a reference); and the base with gravity
  1e-9 larger, a round-off-sized change after which the chaotic flow goes its own way: the
  scatter against which the other differences are read. Reported: the deflection's peak, its
  mean and standard deviation over the steady window, the RMS difference of the histories
  and of their 0.2 s moving averages against the base.
"""

import argparse
import json
import math
import os
import sys
import tomllib
from pathlib import Path

from demfem_post import read_csv
from studies.sweep_study import (DONE, last_exit, last_message, members_of, run_study_sweep,
                                 sweep_file_text)

ROOT = Path(__file__).resolve().parents[2]
PROBE = "lmp"  # the measurement position of cases/sheet_ci.toml (60 mm from the free end)
SCHEMES = ("just_in_time", "predictive")
AVERAGING = (False, True)
DT_F = (1e-4, 2e-4, 5e-4, 1e-3)
GRAVITY = [0.0, 0.0, -9.81]
# gravity 1e-9 larger: a round-off-sized change (the chaotic flow's scatter)
GRAVITY_PERTURBED = [0.0, 0.0, -9.81000000981]
# The fill made once and shared; the [[post]] plots of every member are not needed here.
EXECUTION = {"beds": "shared", "args": ["--no-post"]}


def moving_average(v, n):
    out, s = [], 0.0
    prefix = [0.0]
    for x in v:
        s += x
        prefix.append(s)
    for i in range(len(v)):
        a, b = max(0, i - n), min(len(v), i + n + 1)
        out.append((prefix[b] - prefix[a]) / (b - a))
    return out


def _end_time(end_time):
    return [("end_time", {"run.end_time": [end_time]})] if end_time is not None else []


def _series(member):
    """(time, deflection at the probe) of a done member, and its coupling.csv's columns."""
    c = read_csv(Path(member.folder) / "coupling.csv").lists()
    m = read_csv(Path(member.folder) / "fem_monitor.csv").lists()
    return c, m["time"], m[f"{PROBE}_uz"]


def stability(a):
    parameters = [("scheme", {"coupling.scheme": list(SCHEMES)}),
                  ("force_averaging", {"coupling.force_averaging": list(AVERAGING)}),
                  ("dt_f", {"fem.dt": list(DT_F)})] + _end_time(a.end_time)
    text = sweep_file_text("stability", a.base, parameters, [], EXECUTION)
    run_study_sweep(a.work, "stability", text, a.demfem_run, ["--skip-failed"])
    rows = []
    for member, state, rec in members_of(a.work, "stability"):
        v = member.values
        res = {"member": f"{v['scheme']}_{'avg' if v['force_averaging'] else 'last'}_"
                         f"{v['dt_f']:g}",
               "scheme": v["scheme"], "force_averaging": v["force_averaging"],
               "dt_f": v["dt_f"], "status": last_exit(rec), "state": state,
               "wall_s": rec.get("run_time", math.nan),
               "message": "" if state == DONE else last_message(member, rec)}
        if state == DONE:
            c, _, uz = _series(member)
            res.update(max_overlap=max(c["max_overlap"]),
                       max_energy_error=max(abs(x) for x in c["energy_error"]),
                       end_time=c["time"][-1], max_abs_uz=max(abs(u) for u in uz))
        res["stable"] = (state == DONE and res["max_overlap"] < 0.1 * a.rmin and
                         res["max_abs_uz"] < 0.1)
        rows.append(res)
        print(f"{res['scheme']:13s} avg={str(res['force_averaging']).lower():5s} "
              f"dt_F={res['dt_f']:<6g}: {'stable' if res['stable'] else 'UNSTABLE':8s} "
              f"exit {res['status']}, max overlap {res.get('max_overlap', math.nan):.3g} m, "
              f"max |uz| {res.get('max_abs_uz', math.nan):.4g} m, "
              f"|energy error| {res.get('max_energy_error', math.nan):.3g} J, "
              f"{res['wall_s']:.0f} s {res['message']}", flush=True)
    return rows


def convergence(a):
    scene = tomllib.loads(Path(a.base).read_text())
    dt_d = scene["dem"]["dt"]
    cells = scene["fem"]["mesh"]["plate"]["cells"]
    threads = scene["dem"].get("threads", 1) or 1
    gravity = scene["dem"].get("gravity", GRAVITY)
    variants = {  # name -> (dem.dt, fem.mesh.plate.cells, dem.threads, dem.gravity)
        "base": (dt_d, cells, threads, gravity),
        "dt_dem_half": (dt_d / 2, cells, threads, gravity),
        "mesh_5mm": (dt_d, [2 * cells[0], 2 * cells[1]], threads, gravity),
        "threads_2": (dt_d, cells, 2, gravity),
        "perturbed": (dt_d, cells, threads, GRAVITY_PERTURBED),
    }
    if a.members:
        variants = {k: v for k, v in variants.items() if k in a.members or k == "base"}
    names = list(variants)
    keys = {"dem.dt": [], "fem.mesh.plate.cells": [], "dem.threads": [], "dem.gravity": []}
    for v in variants.values():
        for key, x in zip(keys, v):
            keys[key].append(x)
    # one axis of zipped keys: setting i is variant names[i]
    text = sweep_file_text("convergence", a.base, [("dem.dt", keys)] + _end_time(a.end_time),
                           [], EXECUTION)
    run_study_sweep(a.work, "convergence", text, a.demfem_run)
    results = {}
    for member, state, rec in members_of(a.work, "convergence"):
        name = names[member.setting]
        results[name] = {"status": last_exit(rec), "wall_s": rec.get("run_time", math.nan),
                         "message": last_message(member, rec)}
        if state == DONE:
            _, t, uz = _series(member)
            results[name].update(time=t, uz=uz)
    return convergence_table(results, a.window)


def convergence_table(results, window):
    ref = results["base"]
    rows = []
    for k, r in results.items():
        if "uz" not in r or "uz" not in ref:
            rows.append({"member": k, "status": r["status"], "message": r["message"]})
            print(f"{k}: no result (exit {r['status']}) {r['message']}")
            continue
        t, uz = r["time"], r["uz"]
        n = min(len(uz), len(ref["uz"]))
        step = (t[n - 1] - t[0]) / max(1, n - 1)
        half = max(1, int(round(0.1 / step)))
        sm, sm_ref = moving_average(uz[:n], half), moving_average(ref["uz"][:n], half)
        rms = math.sqrt(sum((uz[i] - ref["uz"][i]) ** 2 for i in range(n)) / n)
        rms_sm = math.sqrt(sum((sm[i] - sm_ref[i]) ** 2 for i in range(n)) / n)
        w = [uz[i] for i in range(n) if window[0] <= t[i] <= window[1]]
        mean = sum(w) / len(w) if w else float("nan")
        sd = math.sqrt(sum((x - mean) ** 2 for x in w) / len(w)) if w else float("nan")
        ip = min(range(n), key=lambda i: uz[i])
        row = {"member": k, "status": r["status"], "wall_s": r["wall_s"], "peak_uz": uz[ip],
               "peak_time": t[ip], "steady_mean": mean, "steady_std": sd, "rms_diff": rms,
               "rms_diff_smoothed": rms_sm}
        rows.append(row)
        print(f"{k:12s} exit {r['status']}: peak {1e3 * uz[ip]:8.3f} mm at {t[ip]:.4f} s, "
              f"steady {window[0]}-{window[1]} s mean {1e3 * mean:7.3f} mm sd {1e3 * sd:6.3f} "
              f"mm, RMS diff to base {1e3 * rms:6.3f} mm (smoothed {1e3 * rms_sm:6.3f} mm), "
              f"{r['wall_s']:.0f} s", flush=True)
    return rows


def main(argv):
    p = argparse.ArgumentParser(prog="python3 -m studies sheet",
                                description=__doc__.split("\n")[0])
    p.add_argument("study", choices=["stability", "convergence"])
    p.add_argument("--base", default=str(ROOT / "cases" / "sheet_ci.toml"))
    p.add_argument("--work", default=str(ROOT / "out" / "sheet_study"))
    p.add_argument("--bin", default=str(ROOT / "build" / "bin"))
    p.add_argument("--rmin", type=float, default=0.0025, help="smallest grain radius, m")
    p.add_argument("--window", default="0.45,0.8", help="steady window for convergence, s")
    p.add_argument("--members", default=None,
                   help="convergence: comma-separated members to run (the base always runs)")
    p.add_argument("--end-time", type=float, default=None,
                   help="run every member to this time instead of the base's run.end_time")
    a = p.parse_args(argv)
    a.base = os.path.abspath(a.base)
    a.work = os.path.abspath(a.work)
    a.demfem_run = os.path.join(os.path.abspath(a.bin), "demfem_run")
    a.members = a.members.split(",") if a.members else None
    a.window = tuple(float(x) for x in a.window.split(","))
    rows = stability(a) if a.study == "stability" else convergence(a)
    with open(os.path.join(a.work, f"{a.study}.json"), "w") as f:
        json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
