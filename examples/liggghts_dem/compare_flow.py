#!/usr/bin/python3
"""Grains flowing onto the sheet with LIGGGHTS and with dem_server, side by side
(docs/liggghts.md, "Grains flowing onto the sheet").

Runs sheet_flow_ci.toml (liggghts_dem, one rank) and sheet_flow_ci_dem_server.toml for each
seed (run.seed; two runs at a time) and prints, per run and per DEM, the mass flow (the slope
of the mass that has left the chamber over 0.1-0.5 s: dem_server's mass_flow sensor,
LIGGGHTS's mass(all,below) of the deck), the deflection at the measurement point (x = 0.28 m)
and the sheet's load (means over 0.3-0.6 s, fem_monitor.csv), with each DEM's band over the
seeds (smallest to largest) and whether the bands overlap. Minutes per run (the figures of
docs/liggghts.md: 33-58 s with dem_server, 68-363 s with LIGGGHTS on a loaded 2-core machine).

  compare_flow.py [--build BUILD] [--seeds 1 2 3] [--output-dir DIR]
"""

import argparse
import concurrent.futures
import csv
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
FLOW_WINDOW = (0.1, 0.5)    # s: the stream leaves the chamber steadily
SHEET_WINDOW = (0.3, 0.6)   # s: the stream on the sheet, its load steady


def run(build, scene, out, seed, liggghts):
    cmd = [str(build / "bin" / "demfem_run"), str(HERE / scene), "--output-dir", str(out),
           "--set", f"run.seed={seed}"]
    if liggghts:
        cmd += ["--set", f'dem.command=["{build / "bin" / "liggghts_dem"}"]']
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV, cwd=HERE)
    if r.returncode != 0:
        sys.exit(f"{scene} seed {seed}: exit {r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    wall = [line.split()[3] for line in r.stdout.splitlines() if line.startswith("wall time: total")]
    return float(wall[0]) if wall else float("nan")


def slope(points):
    n = len(points)
    mt = sum(t for t, _ in points) / n
    mm = sum(m for _, m in points) / n
    return sum((t - mt) * (m - mm) for t, m in points) / sum((t - mt) ** 2 for t, _ in points)


def measure(out, liggghts):
    if liggghts:
        with open(out / "liggghts_outflow.txt") as f:
            crossed = [tuple(map(float, line.split())) for line in f if not line.startswith("time")]
    else:
        with open(out / "sensor_outflow.csv") as f:
            crossed = [(float(r["time"]), float(r["mass_crossed"])) for r in csv.DictReader(f)]
    flow = slope([(t, m) for t, m in crossed if FLOW_WINDOW[0] <= t <= FLOW_WINDOW[1]])
    with open(out / "fem_monitor.csv") as f:
        rows = [r for r in csv.DictReader(f) if SHEET_WINDOW[0] <= float(r["time"]) <= SHEET_WINDOW[1]]
    deflection = statistics.fmean(float(r["lmp_uz"]) for r in rows)
    load = -statistics.fmean(float(r["force_z"]) for r in rows)
    return {"mass flow (kg/s)": flow, "deflection (mm)": 1e3 * deflection, "load (N)": load}


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--build", type=Path, default=HERE.parents[1] / "build")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--output-dir", type=Path, default=Path("out/compare_flow"))
    a = p.parse_args(argv)
    jobs = [(name, scene, seed, name == "LIGGGHTS")
            for seed in a.seeds
            for name, scene in (("dem_server", "sheet_flow_ci_dem_server.toml"),
                                ("LIGGGHTS", "sheet_flow_ci.toml"))]
    results = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        futures = {pool.submit(run, a.build, scene, a.output_dir.resolve() / f"{name}_{seed}",
                               seed, liggghts): (name, seed, liggghts)
                   for name, scene, seed, liggghts in jobs}
        for future in concurrent.futures.as_completed(futures):
            name, seed, liggghts = futures[future]
            values = measure(a.output_dir.resolve() / f"{name}_{seed}", liggghts)
            values["wall (s)"] = future.result()
            results[(name, seed)] = values
    keys = ["mass flow (kg/s)", "deflection (mm)", "load (N)", "wall (s)"]
    print("DEM          seed  " + "  ".join(k.rjust(17) for k in keys))
    for (name, seed), v in sorted(results.items()):
        print(f"{name:12} {seed:4}  " + "  ".join(f"{v[k]:17.4f}" for k in keys))
    bands = {}
    for name in ("dem_server", "LIGGGHTS"):
        for k in keys[:3]:
            values = [v[k] for (n, _), v in results.items() if n == name]
            bands[(name, k)] = (min(values), statistics.fmean(values), max(values))
    for k in keys[:3]:
        (d0, dm, d1), (l0, lm, l1) = bands[("dem_server", k)], bands[("LIGGGHTS", k)]
        overlap = max(d0, l0) <= min(d1, l1)
        print(f"{k}: dem_server {dm:.4f} [{d0:.4f}, {d1:.4f}], LIGGGHTS {lm:.4f} [{l0:.4f}, "
              f"{l1:.4f}]: bands {'overlap' if overlap else 'apart'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
