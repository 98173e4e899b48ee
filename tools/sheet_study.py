#!/usr/bin/python3
"""Stability and convergence studies of the steel-sheet case (docs/verification.md).

usage: tools/sheet_study.py stability   [--base cases/sheet_ci.toml] [--work DIR] [--bin DIR]
                                        [--end-time T]
       tools/sheet_study.py convergence [--base cases/sheet_ci.toml] [--work DIR] [--bin DIR]
                                        [--end-time T] [--window A,B]

Each member is the base scene with some keys replaced (the text of the scene, first match of
each key in its section), written next to the base scene (so that its relative paths hold)
as .study_<member>.toml, and run with `demfem_run --quiet --no-post` in WORK/<member> (the
prepare scene of the base, e.g. the CI fill, is made once in WORK and shared). The table
goes to stdout and WORK/<study>.json.

stability: every scheme (just_in_time, predictive) with and without force averaging at
  dt_F = 1e-4, 2e-4, 5e-4 and 1e-3 s (dt_D fixed). A member is stable when the run ends
  (exit 0, no blow-up exit 3: the scene's bound coupling.blowup.max_overlap and the finite
  checks hold), the largest particle-sheet overlap stays below 10 % of the smallest grain
  radius, and the deflection at the probe stays within 0.1 m (a third of the sheet).
convergence: the base; dt_D halved; the shell mesh refined to 5 mm; the base on two threads
  (the CPU backend gives the same bits: a check, not a reference); and the base with gravity
  1e-9 larger, a round-off-sized change after which the chaotic flow goes its own way: the
  scatter against which the other differences are read. Reported: the deflection's peak, its mean
  and standard deviation over the steady window, the RMS difference of the histories and of
  their 0.2 s moving averages against the base.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import time

from demfem_post import read_csv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def set_key(text, section, key, value):
    """Replaces `key = ...` inside [section] (the first such line after the header)."""
    head = text.find(f"[{section}]\n")
    if head < 0:
        raise KeyError(f"no section [{section}]")
    m = re.compile(rf"^{re.escape(key)}\s*=.*$", re.M).search(text, head)
    if not m:
        raise KeyError(f"no key {key} in [{section}]")
    return text[:m.start()] + f"{key} = {value}" + text[m.end():]


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


END_TIME = None  # --end-time: replaces run.end_time of every member
MEMBERS = None   # --members: only these convergence members (and the base)


def run_member(name, text, base, work, bin_dir):
    scene = os.path.join(os.path.dirname(base), f".study_{name}.toml")
    text = set_key(text, "run", "name", f'"{name}"')
    if END_TIME is not None:
        text = set_key(text, "run", "end_time", repr(END_TIME))
    with open(scene, "w") as f:
        f.write(text)
    t0 = time.time()
    r = subprocess.run([os.path.join(bin_dir, "demfem_run"), "--bin-dir", bin_dir, scene,
                        "--quiet", "--no-post"], cwd=work, capture_output=True, text=True)
    wall = time.time() - t0
    os.remove(scene)
    out = os.path.join(work, "out", name)
    res = {"member": name, "status": r.returncode, "wall_s": wall,
           "message": (r.stderr.strip().splitlines() or [""])[-1][:300]}
    try:
        c = read_csv(os.path.join(out, "coupling.csv")).lists()
        res["max_overlap"] = max(c["max_overlap"]) if c["max_overlap"] else None
        res["max_energy_error"] = max(abs(x) for x in c["energy_error"]) if c["energy_error"] else None
        res["end_time"] = c["time"][-1] if c["time"] else 0.0
        m = read_csv(os.path.join(out, "fem_monitor.csv")).lists()
        res["time"], res["uz"] = m["time"], m["lmp_uz"]
        res["max_abs_uz"] = max(abs(u) for u in m["lmp_uz"])
    except (OSError, KeyError, ValueError, IndexError):
        pass
    return res


def stability(base, work, bin_dir, rmin):
    text = open(base).read()
    rows = []
    for scheme in ("just_in_time", "predictive"):
        for avg in ("false", "true"):
            for dtf in ("1e-4", "2e-4", "5e-4", "1e-3"):
                name = f"{scheme}_{'avg' if avg == 'true' else 'last'}_{dtf}"
                t = set_key(text, "coupling", "scheme", f'"{scheme}"')
                t = set_key(t, "coupling", "force_averaging", avg)
                t = set_key(t, "fem", "dt", dtf)
                res = run_member(name, t, base, work, bin_dir)
                ok = (res["status"] == 0 and res.get("max_overlap") is not None
                      and res["max_overlap"] < 0.1 * rmin and res.get("max_abs_uz", 1) < 0.1)
                res.update({"scheme": scheme, "force_averaging": avg == "true", "dt_f": float(dtf),
                            "stable": ok})
                res.pop("time", None), res.pop("uz", None)
                rows.append(res)
                print(f"{scheme:13s} avg={avg:5s} dt_F={dtf:5s}: {'stable' if ok else 'UNSTABLE':8s} "
                      f"exit {res['status']}, max overlap {res.get('max_overlap', float('nan')):.3g} m, "
                      f"max |uz| {res.get('max_abs_uz', float('nan')):.4g} m, "
                      f"|energy error| {res.get('max_energy_error', float('nan')):.3g} J, "
                      f"{res['wall_s']:.0f} s {res['message'] if res['status'] else ''}", flush=True)
    return rows


def convergence(base, work, bin_dir, window):
    text = open(base).read()
    dtd = float(re.search(r"^\[dem\]\n(?:.*\n)*?dt = ([0-9.e-]+)", text, re.M).group(1))
    cells = re.search(r"^cells = \[(\d+), (\d+)\]", text, re.M)
    members = {
        "base": text,
        "dt_dem_half": set_key(text, "dem", "dt", repr(dtd / 2)),
        "mesh_5mm": set_key(text, "fem.mesh.plate", "cells",
                            f"[{2 * int(cells.group(1))}, {2 * int(cells.group(2))}]"),
        "threads_2": set_key(text, "dem", "threads", "2"),
        # gravity 1e-9 larger: a round-off-sized change, after which the chaotic flow goes
        # its own way (the scatter against which the differences above are read)
        "perturbed": text.replace("[dem]\n", "[dem]\ngravity = [0.0, 0.0, -9.81000000981]\n", 1),
    }
    if MEMBERS:
        members = {k: v for k, v in members.items() if k in MEMBERS or k == "base"}
    results = {k: run_member(k, t, base, work, bin_dir) for k, t in members.items()}
    ref = results["base"]
    rows = []
    for k, r in results.items():
        if "uz" not in r:
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
              f"steady {window[0]}-{window[1]} s mean {1e3 * mean:7.3f} mm sd {1e3 * sd:6.3f} mm, "
              f"RMS diff to base {1e3 * rms:6.3f} mm (smoothed {1e3 * rms_sm:6.3f} mm), "
              f"{r['wall_s']:.0f} s", flush=True)
    return rows


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("study", choices=["stability", "convergence"])
    p.add_argument("--base", default=os.path.join(ROOT, "cases", "sheet_ci.toml"))
    p.add_argument("--work", default=os.path.join(ROOT, "out", "sheet_study"))
    p.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    p.add_argument("--rmin", type=float, default=0.0025, help="smallest grain radius, m")
    p.add_argument("--window", default="0.45,0.8", help="steady window for convergence, s")
    p.add_argument("--members", default=None,
                   help="convergence: comma-separated members to run (the base always runs)")
    p.add_argument("--end-time", type=float, default=None,
                   help="run every member to this time instead of the base's run.end_time")
    a = p.parse_args(argv)
    global END_TIME, MEMBERS
    END_TIME = a.end_time
    MEMBERS = a.members.split(",") if a.members else None
    os.makedirs(a.work, exist_ok=True)
    base = os.path.abspath(a.base)
    if a.study == "stability":
        rows = stability(base, a.work, os.path.abspath(a.bin), a.rmin)
    else:
        w = tuple(float(x) for x in a.window.split(","))
        rows = convergence(base, a.work, os.path.abspath(a.bin), w)
    with open(os.path.join(a.work, f"{a.study}.json"), "w") as f:
        json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
