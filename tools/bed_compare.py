#!/usr/bin/python3
"""Prepared beds side by side: the statistics of their `packing` sensors with
`contacts = true` (docs/scene_dem.md) at the end of each run, as a table and depth profiles.

usage: tools/bed_compare.py OUTPUT_DIR [OUTPUT_DIR ...] [--bed packing_bed] [--slabs slab_]
                            [--slab-height 0.04] [--count all_rocks] [--png FILE.png]

For each output folder (a run of cases/sleeper_prep_tiled_mid.toml or
cases/sleeper_prep_poured_mid.toml, or any scene with such sensors): the last row of
sensor_<bed>.csv (the bulk: solid fraction, coordination Z with and without rattlers, the
rattlers' share, mean contact force <f>, fraction of contacts above 2<f>, the exponential
tail's rate beta, vertical stress), the rocks in the run (the `particles` of
sensor_<count>.csv), and the slabs sensor_<slabs>1.csv, sensor_<slabs>2.csv, ... (from the
floor up, each --slab-height thick from z = 0): solid fraction, Z without rattlers and
vertical stress at each slab's mid-height (a folder named *poured* and not *tiled* is drawn
dashed; a run without the count or slab sensors shows
none). Prints a Markdown table; with --png draws the
depth profiles, one line per folder. Exit status 2 on a missing or empty sensor file.
"""

import argparse
import os
import sys

from demfem_post import read_csv
from demfem_post.plots import pyplot

BULK = [("solid_fraction", "solid fraction", "{:.3f}"), ("coordination", "Z", "{:.2f}"),
        ("coordination_no_rattlers", "Z without rattlers", "{:.2f}"),
        ("rattler_share", "rattlers", "{:.3f}"), ("force_mean", "<f> (N)", "{:.2f}"),
        ("force_above_2mean", "f > 2<f>", "{:.3f}"), ("force_tail_decay", "tail beta", "{:.2f}"),
        ("stress_zz", "stress_zz (Pa)", "{:.0f}")]


def last_row(folder, sensor):
    path = os.path.join(folder, f"sensor_{sensor}.csv")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such sensor file")
    table = read_csv(path, incomplete_rows="skip", text_as_nan=True)
    if len(table["time"]) == 0:
        raise ValueError(f"{path}: no rows")
    row = {name: float(table[name][-1]) for name in table.header}
    if "rattlers" in row and row.get("particles", 0) > 0:
        row["rattler_share"] = row["rattlers"] / row["particles"]
    return row


def rocks(folder, sensor):
    """The `particles` of sensor_<sensor>.csv's last row, None without that sensor."""
    if not os.path.isfile(os.path.join(folder, f"sensor_{sensor}.csv")):
        return None
    return last_row(folder, sensor)["particles"]


def slabs(folder, prefix, height):
    out = []
    while os.path.isfile(os.path.join(folder, f"sensor_{prefix}{len(out) + 1}.csv")):
        row = last_row(folder, f"{prefix}{len(out) + 1}")
        row["z"] = (len(out) + 0.5) * height
        out.append(row)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folders", nargs="+")
    p.add_argument("--bed", default="packing_bed")
    p.add_argument("--slabs", default="slab_")
    p.add_argument("--slab-height", type=float, default=0.04)
    p.add_argument("--count", default="all_rocks")
    p.add_argument("--png")
    a = p.parse_args()
    try:
        beds = [(f, last_row(f, a.bed), rocks(f, a.count), slabs(f, a.slabs, a.slab_height))
                for f in a.folders]
    except (FileNotFoundError, ValueError, KeyError) as e:
        print(f"bed_compare.py: {e}", file=sys.stderr)
        return 2
    print("| bed | rocks | time (s) | " + " | ".join(label for _, label, _ in BULK) + " |")
    print("| --- " * (len(BULK) + 3) + "|")
    for folder, bulk, count, _ in beds:
        cells = [fmt.format(bulk[key]) if key in bulk else "–" for key, _, fmt in BULK]
        count = "–" if count is None else f"{count:.0f}"
        print(f"| {os.path.basename(os.path.normpath(folder))} | {count} | "
              f"{bulk['time']:g} | " + " | ".join(cells) + " |")
    for folder, _, _, profile in beds:
        for s in profile:
            print(f"{os.path.basename(os.path.normpath(folder))} slab z {s['z']:.3f} m: solid "
                  f"fraction {s['solid_fraction']:.3f}, Z {s['coordination']:.2f}, Z without "
                  f"rattlers {s.get('coordination_no_rattlers', float('nan')):.2f}, stress_zz "
                  f"{s.get('stress_zz', float('nan')):.0f} Pa, <f> "
                  f"{s.get('force_mean', float('nan')):.2f} N")
    if a.png:
        plt = pyplot()
        fig, axes = plt.subplots(1, 3, figsize=(11, 3.6), sharey=True)
        for folder, _, _, profile in beds:
            z = [s["z"] for s in profile]
            label = os.path.basename(os.path.normpath(folder))
            style = "--" if "poured" in label and "tiled" not in label else "-"  # poured: dashed
            for ax, key in zip(axes, ("solid_fraction", "coordination_no_rattlers", "stress_zz")):
                ax.plot([s.get(key, float("nan")) for s in profile], z, style, marker="o",
                        label=label)
        for ax, title in zip(axes, ("solid fraction", "Z without rattlers", "stress_zz (Pa)")):
            ax.set_xlabel(title)
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("slab mid-height above the floor (m)")
        axes[-1].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(a.png, dpi=110)
        print(f"wrote {a.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
