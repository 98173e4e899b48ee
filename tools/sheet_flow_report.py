#!/usr/bin/python3
"""The phases of a steel-sheet rig's discharge from its mass-flow sensors (DEM-only runs such as
cases/sheet_tail_flow_coarse.toml, or any sheet run's output).

usage: tools/sheet_flow_report.py OUTPUT_DIR [--sensor outflow] [--outlet outlet]
                                  [--steady 0.3,1.5] [--drop 0.9] [--smooth 0.3]
                                  [--total 6.0] [--at 4.5,5.0] [--figure PNG] [--csv CSV]

Reads OUTPUT_DIR/sensor_<sensor>.csv (mass flow through the plane under the flaps, eq. 2.26)
and, when present, OUTPUT_DIR/sensor_<outlet>.csv (through the outlet itself), and prints:
the peak (time, rate); the near-constant phase (mean, sd, min, max over --steady); when the
reduction starts: the first time after the steady window from which the rate, smoothed over
--smooth seconds, stays below --drop times the steady mean to the end of the run; the mean
rate of each 0.5 s after that; the mass that crossed by each time of --at, also as a fraction
of --total (the grain in the chamber at the start), and when 50 / 90 / 95 / 99 % of the
final mass had crossed. --csv writes time, rate, smoothed rate and mass crossed (both
sensors); --figure the plot. The numbers go to stdout and OUTPUT_DIR/flow_report.json.
Exit status 2 on a missing file or column.
"""

import argparse
import json
import os
import sys

from demfem_post import read_csv
from demfem_post.plots import pyplot_or_exit
from demfem_post.windows import moving_average, stats, window


def pair(text):
    a, b = (float(x) for x in text.split(","))
    return a, b


def series(out_dir, name):
    path = os.path.join(out_dir, f"sensor_{name}.csv")
    cols = read_csv(path)
    return cols.column("time"), cols.column("mass_flow"), cols.column("mass_crossed")


def mass_at(t, mass, when):
    """Mass crossed by `when` (the last sample at or before it), None past the run's end."""
    if when > t[-1] + 1e-9:
        return None
    return max((m for s, m in zip(t, mass) if s <= when + 1e-9), default=0.0)


def phases(t, rate, mass, steady, drop, smooth_width, total, at):
    i = max(range(len(rate)), key=lambda k: rate[k])
    smooth = moving_average(t, rate, smooth_width)
    res = {"peak": {"time": t[i], "rate": rate[i]}, "steady": None, "reduction_start": None,
           "after_reduction": [], "mass_at": {}, "final_mass": mass[-1], "end_time": t[-1]}
    s = stats(window(t, rate, *steady))
    if s:
        s.update({"from": steady[0], "to": steady[1]})
        res["steady"] = s
        limit = drop * s["mean"]
        start = None
        for k in range(len(t)):
            if t[k] <= steady[1]:
                continue
            if smooth[k] < limit:
                start = k if start is None else start
            else:
                start = None
        if start is not None:
            res["reduction_start"] = {"time": t[start], "smoothed_rate": smooth[start],
                                      "threshold": limit, "mass_crossed": mass[start]}
            lo = t[start]
            while lo + 0.5 <= t[-1] + 1e-9:
                w = stats(window(t, rate, lo + 1e-9, lo + 0.5))
                res["after_reduction"].append({"from": lo, "to": lo + 0.5, "mean_rate": w["mean"]})
                lo += 0.5
    for when in at:
        m = mass_at(t, mass, when)
        res["mass_at"][f"{when:g}"] = None if m is None else {"mass": m, "fraction": m / total}
    for q in (0.5, 0.9, 0.95, 0.99):
        k = next((k for k, m in enumerate(mass) if m >= q * mass[-1]), None)
        res[f"time_{int(q * 100)}pct"] = t[k] if k is not None and mass[-1] > 0 else None
    return res, smooth


def text(name, r, total):
    lines = [f"{name}: peak {r['peak']['rate']:.3f} kg/s at {r['peak']['time']:.2f} s"]
    if r["steady"]:
        s = r["steady"]
        lines.append(f"  steady {s['mean']:.3f} kg/s (sd {s['std']:.3f}, {s['min']:.2f}-"
                     f"{s['max']:.2f}) over {s['from']:g}-{s['to']:g} s")
    if r["reduction_start"]:
        d = r["reduction_start"]
        lines.append(f"  reduction from {d['time']:.2f} s (smoothed rate below {d['threshold']:.3f} "
                     f"kg/s to the end; {d['mass_crossed']:.2f} kg crossed then)")
        lines.append("  then per 0.5 s: " + ", ".join(
            f"{w['from']:.2f}-{w['to']:.2f} s {w['mean_rate']:.3f}" for w in r["after_reduction"]))
    else:
        lines.append("  no reduction within the run")
    for when, m in r["mass_at"].items():
        lines.append(f"  crossed by {when} s: " + ("not reached" if m is None else
                     f"{m['mass']:.3f} kg ({100 * m['fraction']:.1f} % of {total:g} kg)"))
    lines.append(f"  final {r['final_mass']:.3f} kg at {r['end_time']:.2f} s; 50/90/95/99 % of it by "
                 + " / ".join("-" if r[f"time_{q}pct"] is None else f"{r[f'time_{q}pct']:.2f}"
                              for q in (50, 90, 95, 99)) + " s")
    return "\n".join(lines)


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("output_dir")
    p.add_argument("--sensor", default="outflow")
    p.add_argument("--outlet", default="outlet")
    p.add_argument("--steady", type=pair, default=(0.3, 1.5))
    p.add_argument("--drop", type=float, default=0.9)
    p.add_argument("--smooth", type=float, default=0.3)
    p.add_argument("--total", type=float, default=6.0)
    p.add_argument("--at", default="4.5,5.0")
    p.add_argument("--figure")
    p.add_argument("--csv")
    a = p.parse_args(argv)
    at = [float(x) for x in a.at.split(",")]
    try:
        runs = {a.sensor: series(a.output_dir, a.sensor)}
        if os.path.isfile(os.path.join(a.output_dir, f"sensor_{a.outlet}.csv")):
            runs[a.outlet] = series(a.output_dir, a.outlet)
    except (OSError, KeyError, ValueError) as e:
        print(f"sheet_flow_report.py: {e}", file=sys.stderr)
        return 2
    report, smooth = {}, {}
    for name, (t, rate, mass) in runs.items():
        report[name], smooth[name] = phases(t, rate, mass, a.steady, a.drop, a.smooth, a.total, at)
        print(text(name, report[name], a.total))
    with open(os.path.join(a.output_dir, "flow_report.json"), "w") as f:
        json.dump(report, f, indent=1)
    if a.csv:
        t = runs[a.sensor][0]
        names = list(runs)
        with open(a.csv, "w") as f:
            f.write("time," + ",".join(f"{n}_rate,{n}_rate_smoothed,{n}_mass_crossed"
                                       for n in names) + "\n")
            for k in range(len(t)):
                row = [f"{t[k]:.4f}"]
                for n in names:
                    tt, rate, mass = runs[n]
                    if k < len(tt):
                        row += [f"{rate[k]:.5g}", f"{smooth[n][k]:.5g}", f"{mass[k]:.5g}"]
                    else:
                        row += ["", "", ""]
                f.write(",".join(row) + "\n")
    if a.figure:
        plt = pyplot_or_exit("sheet_flow_report.py")

        fig, ax = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
        for n, (t, rate, mass) in runs.items():
            label = "under the flaps (z = 0.26 m)" if n == a.sensor else "outlet (z = 0.36 m)"
            line, = ax[0].plot(t, rate, lw=0.6, alpha=0.5)
            ax[0].plot(t, smooth[n], color=line.get_color(), lw=1.6,
                       label=f"{label}, {a.smooth:g} s mean")
            ax[1].plot(t, mass, color=line.get_color(), label=label)
        r = report[a.sensor]
        if r["reduction_start"]:
            for x in ax:
                x.axvline(r["reduction_start"]["time"], color="grey", ls="--", lw=0.8)
        ax[1].axhline(a.total, color="grey", ls=":", lw=0.8)
        ax[0].set_ylabel("mass flow (kg/s)")
        ax[1].set_ylabel("mass crossed (kg)")
        ax[1].set_xlabel("time (s)")
        ax[0].legend(fontsize=8)
        ax[0].set_title(os.path.basename(os.path.normpath(a.output_dir)), fontsize=9)
        fig.tight_layout()
        fig.savefig(a.figure, dpi=110)
        plt.close(fig)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
