#!/usr/bin/python3
"""Plot the CSV time series of a demfem run to PNG.

usage: tools/plot_series.py FILE.csv [FILE.csv ...] [--x COLUMN] [--columns A,B,...]
                            [--out-dir DIR | -o FILE.png]

Every column (or those named by --columns) is drawn against the x column (default "time",
else the first column) in its own panel; one PNG per CSV, named like the CSV
(out/beam_fixed/coupling.csv -> out/beam_fixed/coupling.png) unless --out-dir/-o say
otherwise. Uses matplotlib (Debian: python3-matplotlib) with the Agg backend, so no display
is needed. Exit status 2 on a missing file, an unknown column or a CSV without data.
"""

import argparse
import math
import os
import sys

from demfem_post import read_csv, tool_errors
from demfem_post.plots import pyplot


def plot(path, x_name, columns, out):
    plt = pyplot()

    table = read_csv(path, incomplete_rows="error", text_as_nan=True)
    header, cols = table.header, table.lists()
    if x_name is None:
        x_name = "time" if "time" in cols else header[0]
    if x_name not in cols:
        raise KeyError(f"{path}: no column '{x_name}' (columns: {', '.join(header)})")
    names = columns or [h for h in header if h != x_name and h != "step"]
    for n in names:
        if n not in cols:
            raise KeyError(f"{path}: no column '{n}' (columns: {', '.join(header)})")
    ncols = 2 if len(names) > 3 else 1
    nrows = math.ceil(len(names) / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(6 * ncols, 2.2 * nrows), squeeze=False,
                             sharex=True)
    for ax, n in zip(axes.flat, names):
        ax.plot(cols[x_name], cols[n], lw=1)
        ax.set_ylabel(n)
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(x_name)
    fig.suptitle(os.path.basename(path))
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("csv", nargs="+")
    p.add_argument("--x", default=None, help="x column (default: time)")
    p.add_argument("--columns", default=None, help="comma-separated columns to plot")
    p.add_argument("--out-dir", default=None, help="folder for the PNG files")
    p.add_argument("-o", "--output", default=None, help="PNG file (one CSV only)")
    a = p.parse_args(argv)
    if a.output and len(a.csv) != 1:
        p.error("-o takes one CSV; use --out-dir for several")
    columns = [c.strip() for c in a.columns.split(",")] if a.columns else None
    with tool_errors("plot_series.py"):
        for path in a.csv:
            if not os.path.isfile(path):
                raise FileNotFoundError(f"{path}: no such file")
            if a.output:
                out = a.output
            else:
                base = os.path.splitext(os.path.basename(path))[0] + ".png"
                out = os.path.join(a.out_dir or os.path.dirname(path) or ".", base)
            if os.path.dirname(out):
                os.makedirs(os.path.dirname(out), exist_ok=True)
            print(plot(path, a.x, columns, out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
