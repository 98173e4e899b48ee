#!/usr/bin/python3
"""Angle of repose of rock heaps beside sphere heaps (issue 18, docs/polyhedra.md "Heap").

Runs cases/heap_repose_rocks.toml (1000 rocks of 30 triangles) and its sphere reference
cases/heap_repose_rocks_ref.toml (1000 spheres of the same diameters) at each particle
friction, one after the other with one thread each, then writes a table (heap_study.json)
and a figure (heap_study.png: the angle over time and the final angle against friction).
The angle of a run is the mean of the repose sensor over its last `--window` seconds (the
heap has settled; the kinetic energy then is reported beside it).

  /usr/bin/python3 tools/heap_study.py --out out/heap_study --friction 0.3 0.6 0.9
  /usr/bin/python3 tools/heap_study.py --out out/heap_study --plot-only
"""
import argparse
import json
import math
import os
import subprocess
import sys

from demfem_post import MissingModule, read_csv
from demfem_post.plots import pyplot

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = {"rocks": "cases/heap_repose_rocks.toml", "spheres": "cases/heap_repose_rocks_ref.toml"}


def summarise(folder, window):
    rep = read_csv(os.path.join(folder, "sensor_repose.csv")).lists()
    ke = read_csv(os.path.join(folder, "sensor_energy.csv")).lists()
    flow = read_csv(os.path.join(folder, "sensor_outflow.csv")).lists()
    t_end = rep["time"][-1]
    last = [a for t, a in zip(rep["time"], rep["angle_deg"]) if t >= t_end - window - 1e-9]
    last = [a for a in last if not math.isnan(a)]
    return {
        "angle_deg": sum(last) / len(last) if last else float("nan"),
        "angle_min": min(last) if last else float("nan"),
        "angle_max": max(last) if last else float("nan"),
        "samples": len(last),
        "final_angle_deg": rep["angle_deg"][-1],
        "heap_radius_m": rep["heap_radius"][-1],
        "heap_height_m": rep["heap_height"][-1],
        "kinetic_energy_J": ke["kinetic_energy"][-1],
        "mass_passed_kg": flow["mass_crossed"][-1],
        "end_time_s": t_end,
        "series": {"time": rep["time"], "angle_deg": rep["angle_deg"]},
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--out", default="out/heap_study")
    ap.add_argument("--friction", type=float, nargs="+", default=[0.3, 0.6, 0.9])
    ap.add_argument("--kinds", nargs="+", default=["spheres", "rocks"], choices=list(SCENES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--window", type=float, default=0.2, help="s at the end averaged")
    ap.add_argument("--end-time", type=float, default=None, help="s (default: the scenes')")
    ap.add_argument("--plot-only", action="store_true")
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build", "bin"),
                    help="folder with demfem_run and dem_server")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    runner = os.path.join(a.bin_dir, "demfem_run")
    results = {}
    for mu in a.friction:
        for kind in a.kinds:
            folder = os.path.join(a.out, f"{kind}_mu{mu:g}_seed{a.seed}")
            if not a.plot_only:
                cmd = [runner, "--quiet", "--no-post", "--bin-dir", a.bin_dir, "--output-dir", folder,
                       os.path.join(ROOT, SCENES[kind]), "--set", f"dem.pairs[0].friction={mu}",
                       "--set", f"run.seed={a.seed}"]
                if a.end_time is not None:
                    cmd += ["--set", f"run.end_time={a.end_time}"]
                print(" ".join(cmd), flush=True)
                r = subprocess.run(cmd)
                if r.returncode != 0:
                    sys.exit(f"{kind} at friction {mu}: exit status {r.returncode}")
            if os.path.exists(os.path.join(folder, "sensor_repose.csv")):
                results[f"{kind} {mu:g}"] = dict(kind=kind, friction=mu, seed=a.seed,
                                                 **summarise(folder, a.window))
    print(f"{'particles':10s} {'mu':>5s} {'angle':>7s} {'min':>6s} {'max':>6s} "
          f"{'R m':>7s} {'H m':>7s} {'KE J':>9s} {'passed kg':>9s}")
    for r in results.values():
        print(f"{r['kind']:10s} {r['friction']:5.2f} {r['angle_deg']:7.2f} {r['angle_min']:6.2f} "
              f"{r['angle_max']:6.2f} {r['heap_radius_m']:7.4f} {r['heap_height_m']:7.4f} "
              f"{r['kinetic_energy_J']:9.2e} {r['mass_passed_kg']:9.4f}")
    with open(os.path.join(a.out, f"heap_study_seed{a.seed}.json"), "w") as f:
        json.dump(results, f, indent=1)
    try:
        plt = pyplot()
    except MissingModule as e:
        print(f"heap_study.py: no figure: {e}", file=sys.stderr)
        return
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for r in results.values():
        s = r["series"]
        ax1.plot(s["time"], s["angle_deg"], "-" if r["kind"] == "rocks" else "--",
                 label=f"{r['kind']}, μ = {r['friction']:g}")
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("angle of repose (°)")
    ax1.legend(fontsize=8)
    for kind, m in (("rocks", "o-"), ("spheres", "s--")):
        pts = sorted((r["friction"], r["angle_deg"]) for r in results.values() if r["kind"] == kind)
        if pts:
            ax2.plot([p[0] for p in pts], [p[1] for p in pts], m, label=kind)
    mu = [0.0, 1.0]
    ax2.plot(mu, [math.degrees(math.atan(x)) for x in mu], ":", color="grey", label="atan μ")
    ax2.set_xlabel("particle friction μ")
    ax2.set_ylabel(f"angle of repose (°), mean of the last {a.window:g} s")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, f"heap_study_seed{a.seed}.png"), dpi=110)


if __name__ == "__main__":
    main()
