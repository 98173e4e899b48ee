#!/usr/bin/python3
"""Errors of the sheet CI runs of bench/coupling_schemes (--parts sheet) in two more measures
than the bench's JSON (docs/coupling.md, "Problem (c)").

usage: /usr/bin/python3 tools/sheet_scheme_errors.py RUNS_DIR

RUNS_DIR is the bench's --work folder (default out/bench/coupling_schemes_runs). For every run
folder sheet_ci_<scheme>_<dt_F> that completed, against sheet_ci_implicit-iqn_2e-05_reference,
from fem_monitor.csv (probe lmp, u_z):
  series  largest |w - w_ref| at the common times over the largest |w_ref| (the measure of
          problems a and b);
  mean    |mean w - mean w_ref| / |mean w_ref| over 0.3-0.6 s (the flow on the sheet, a window
          three times the bench's, so less sensitive to the phase of the sheet's oscillation).

usage: /usr/bin/python3 tools/sheet_scheme_errors.py --ensemble REF_RUN... -- RUN...

The granular flow is chaotic: a change of 1e-9 in the sheet's density moves the mean deflection
by up to 1 % (docs/coupling.md, "Problem (c)"), so one run is one sample. This compares two
ensembles of run folders (each a completed run's output, fem_monitor.csv with probe lmp): the
mean deflection over 0.3-0.6 s of every run, each ensemble's average and standard deviation,
and the difference of the averages relative to the reference ensemble's, with its standard
error (the two standard errors of the averages added in quadrature).
"""
import math
import os
import sys

from demfem_post import read_csv


def series(folder):
    path = os.path.join(folder, "fem_monitor.csv")
    if not os.path.exists(path):
        return None
    rows = read_csv(path)
    return list(zip(rows.column("time"), rows.column("lmp_uz")))


def flow_mean(s, a=0.3, b=0.6):
    v = [w for t, w in s if a - 1e-9 <= t <= b + 1e-9]
    return sum(v) / len(v)


def ensemble(argv):
    if "--" not in argv:
        print(__doc__, file=sys.stderr)
        return 2
    cut = argv.index("--")
    groups = (argv[argv.index("--ensemble") + 1:cut], argv[cut + 1:])
    stats = []
    for name, folders in zip(("reference", "runs"), groups):
        means = []
        for folder in folders:
            s = series(folder)
            if not s or s[-1][0] < 0.6 - 1e-9:
                print("%s: no complete run (fem_monitor.csv to 0.6 s)" % folder, file=sys.stderr)
                return 2
            means.append(flow_mean(s))
            print("%-9s %-60s mean deflection %.5g mm" % (name, folder, 1e3 * means[-1]))
        n = len(means)
        if n == 0:
            print("%s: no run folder given" % name, file=sys.stderr)
            return 2
        avg = sum(means) / n
        sd = math.sqrt(sum((m - avg) ** 2 for m in means) / (n - 1)) if n > 1 else float("nan")
        stats.append((avg, sd, n))
        print("%-9s %d runs: average %.5g mm, standard deviation %.3g mm (%.2g %%)"
              % (name, n, 1e3 * avg, 1e3 * sd, 100 * sd / abs(avg)))
    (ra, rs, rn), (a, sd, n) = stats
    se = math.sqrt((rs ** 2 / rn if rn > 1 else 0.0) + (sd ** 2 / n if n > 1 else 0.0))
    print("runs against reference: %+.3g %% (standard error %.2g %%); the runs one by one: %s"
          % (100 * (a - ra) / abs(ra), 100 * se / abs(ra),
             ", ".join("%.2g %%" % (100 * abs(m - ra) / abs(ra))
                       for m in [flow_mean(series(f)) for f in groups[1]])))
    return 0


def main(argv):
    if any(a in ("-h", "--help") for a in argv[1:]):  # not a folder or file named --help
        print(__doc__)
        return 0
    if "--ensemble" in argv:
        return ensemble(argv)
    runs = argv[1] if len(argv) > 1 else "out/bench/coupling_schemes_runs"
    ref = series(os.path.join(runs, "sheet_ci_implicit-iqn_2e-05_reference"))
    if not ref:
        print("no reference run in", runs, file=sys.stderr)
        return 2
    at = {round(t / 2e-5): w for t, w in ref}
    scale = max(abs(w) for _, w in ref)

    def mean(s, a=0.3, b=0.6):
        v = [w for t, w in s if a - 1e-9 <= t <= b + 1e-9]
        return sum(v) / len(v)

    ref_mean = mean(ref)
    print("reference: largest |w| %.4g m, mean over 0.3-0.6 s %.4g m" % (scale, ref_mean))
    print("%-20s %8s %10s %10s" % ("scheme", "dt_F", "series", "mean"))
    for name in sorted(os.listdir(runs)):
        folder = os.path.join(runs, name)
        if not name.startswith("sheet_ci_") or "reference" in name or not os.path.isdir(folder):
            continue
        if not os.path.exists(os.path.join(folder, "timing.csv")):
            continue  # did not complete (blow-up, no convergence)
        s = series(folder)
        if not s or s[-1][0] < 0.6 - 1e-9:
            continue
        scheme, dt = name[len("sheet_ci_"):].rsplit("_", 1)
        err = 0.0
        for t, w in s:
            k = round(t / 2e-5)
            if abs(t / 2e-5 - k) < 1e-6 and k in at:
                err = max(err, abs(w - at[k]))
        print("%-20s %8s %10.3g %10.3g" % (scheme, dt, err / scale,
                                            abs(mean(s) - ref_mean) / abs(ref_mean)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
