#!/usr/bin/python3
"""Plots and key figures of a sleeper-on-ballast run (thesis ch. 6, cases/sleeper*.toml).

usage: tools/sleeper_report.py OUTPUT_DIR [--hold T0,T1] [--cell-area 0.0484]
                               [--load-start 0.2] [--cycle-frequency 100] [--time-scale 1]
                               [--cycles 6]
                               [--ramp 0.03] [--sleeper-mass 72] [--load 22100]

Reads OUTPUT_DIR/fem_monitor.csv (bottom probes b*_uz of the sleeper, total interface force),
OUTPUT_DIR/sensor_cell<k>.csv (force of the rocks on pressure cell k) and
OUTPUT_DIR/sensor_base.csv (force of the rocks on the box), and writes into OUTPUT_DIR:
  settlement.png       settlement of the sleeper (mean uz of the bottom probes, mm) against
                       time, and its value at the cycles' minima against the cycle number
  cell_pressures.png   pressure of each cell (vertical force / top area, kPa) against time
  sleeper_report.txt   the key figures in words
  sleeper_report.json  the same, for scripts and tests
Force balance of the static hold (--hold window, the load held at its peak): the increase of
the base reaction over its value before the sleeper touched (the first row: the prepared
bed's rocks and cells at rest) against the sleeper's weight plus the applied load, and the
force of the rocks on the sleeper (fem_monitor force_z) against the same. Exit status 2 on a
missing file or column.
"""

import argparse
import glob
import json
import math
import os
import re
import sys

# the CSV reading of the sheet report (same folder)
from sheet_report import column, read_csv


def window_mean(t, y, t0, t1):
    v = [b for a, b in zip(t, y) if t0 <= a <= t1]
    return (sum(v) / len(v)) if v else None


def main(argv):
    ap = argparse.ArgumentParser(description="sleeper run report")
    ap.add_argument("output")
    ap.add_argument("--hold", default=None, help="T0,T1: window of the static hold, s")
    ap.add_argument("--cell-area", type=float, default=0.22 * 0.22, help="top area of a cell, m^2")
    ap.add_argument("--load-start", type=float, default=0.2, help="start of the pattern, s")
    ap.add_argument("--ramp", type=float, default=0.03, help="ramp duration (reference), s")
    ap.add_argument("--cycle-frequency", type=float, default=100.0, help="Hz (reference)")
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--cycles", type=int, default=6, help="cycles of the pattern (fig. 6.2: 6)")
    ap.add_argument("--sleeper-mass", type=float, default=800.0 * 2.5 * 0.2 * 0.18, help="kg")
    ap.add_argument("--load", type=float, default=2 * 11e3 + 100.0,
                    help="applied load in the hold (both seats + seating), N")
    a = ap.parse_args(argv)
    out = a.output
    try:
        mon_path = os.path.join(out, "fem_monitor.csv")
        mon = read_csv(mon_path)
        t = column(mon, "time", mon_path)
        probes = sorted({m.group(1) for h in mon for m in [re.match(r"(b\w+)_uz$", h)] if m})
        if not probes:
            raise KeyError(f"{mon_path}: no bottom probes b*_uz")
        uz = [column(mon, p + "_uz", mon_path) for p in probes]
        settle = [1e3 * sum(u[i] for u in uz) / len(uz) for i in range(len(t))]  # mm
        fz_sleeper = column(mon, "force_z", mon_path)
        cells = []
        for path in sorted(glob.glob(os.path.join(out, "sensor_cell*.csv"))):
            c = read_csv(path)
            name = os.path.basename(path)[len("sensor_"):-4]
            # the rocks push the cell down: -fz is the vertical load on it
            cells.append((name, column(c, "time", path),
                          [-f / a.cell_area / 1e3 for f in column(c, "fz", path)]))
        base_path = os.path.join(out, "sensor_base.csv")
        base = read_csv(base_path)
        tb, fb = column(base, "time", base_path), column(base, "fz", base_path)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"sleeper_report.py: {e}", file=sys.stderr)
        return 2

    # settlement at the minima of the cycles (load at cycle_min): reference times T_r + k / f
    ts = a.time_scale
    cyc = []
    k = 0
    while k <= a.cycles:
        tk = a.load_start + ts * (a.ramp + k / a.cycle_frequency)
        if tk > t[-1]:
            break
        i = min(range(len(t)), key=lambda j: abs(t[j] - tk))
        cyc.append((k, settle[i]))
        k += 1

    g = 9.81
    report = {"probes": probes, "final_time": t[-1], "settlement_final_mm": settle[-1],
              "settlement_min_mm": min(settle), "cycles": [{"cycle": k, "settlement_mm": s}
                                                           for k, s in cyc]}
    if a.hold:
        h0, h1 = (float(x) for x in a.hold.split(","))
        base0 = fb[0]
        base_hold = window_mean(tb, fb, h0, h1)
        fs_hold = window_mean(t, fz_sleeper, h0, h1)
        expected = a.sleeper_mass * g + a.load
        report["hold"] = {"window": [h0, h1]}
        if base_hold is not None and fs_hold is not None:
            d_base = -(base_hold - base0)
            report["hold"].update({
                "bed_weight_N": -base0,
                "base_increase_N": d_base,
                "force_on_sleeper_N": -fs_hold,
                "sleeper_weight_plus_load_N": expected,
                "base_balance_rel": (d_base - expected) / expected,
                "sleeper_balance_rel": (-fs_hold - expected) / expected,
                "cell_pressure_kPa": {n: window_mean(tc, p, h0, h1) for n, tc, p in cells},
            })

    with open(os.path.join(out, "sleeper_report.json"), "w") as f:
        json.dump(report, f, indent=1)
    lines = [f"sleeper run {out}: {len(t)} monitor rows up to t = {t[-1]:.4f} s",
             f"settlement (mean uz of {len(probes)} bottom probes): final {settle[-1]:.3f} mm, "
             f"lowest {min(settle):.3f} mm"]
    if cyc:
        lines.append("settlement at the cycle minima: " +
                     ", ".join(f"{k}: {s:.3f}" for k, s in cyc) + " mm")
    if "hold" in report and "base_increase_N" in report["hold"]:
        h = report["hold"]
        lines += [f"static hold {h['window']}: bed (rocks + cells) weight {h['bed_weight_N']:.1f} N; "
                  f"base reaction increase {h['base_increase_N']:.1f} N, force of the rocks on "
                  f"the sleeper {h['force_on_sleeper_N']:.1f} N, against sleeper weight + load "
                  f"{h['sleeper_weight_plus_load_N']:.1f} N: {100 * h['base_balance_rel']:+.2f} % "
                  f"and {100 * h['sleeper_balance_rel']:+.2f} %",
                  "cell pressures (kPa): " + ", ".join(
                      f"{n} {p:.2f}" if p is not None else f"{n} -"
                      for n, p in h["cell_pressure_kPa"].items())]
    with open(os.path.join(out, "sleeper_report.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(t, settle)
    ax[0].set_xlabel("time (s)")
    ax[0].set_ylabel("settlement: mean uz of the bottom (mm)")
    ax[0].grid(True)
    if cyc:
        ax[1].plot([c[0] for c in cyc], [c[1] for c in cyc], "o-")
    ax[1].set_xlabel("cycle")
    ax[1].set_ylabel("settlement at the cycle minimum (mm)")
    ax[1].grid(True)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "settlement.png"), dpi=110)
    fig, ax = plt.subplots(figsize=(7, 4))
    for n, tc, p in cells:
        ax.plot(tc, p, label=n)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("cell pressure: vertical force / top area (kPa)")
    ax.legend()
    ax.grid(True)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "cell_pressures.png"), dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
