#!/usr/bin/python3
"""Figures of bench/coupling_schemes (docs/coupling.md, "Choosing a scheme").

usage: /usr/bin/python3 tools/plot_coupling_schemes.py RESULT.json [MORE.json ...] OUTPUT_DIR

Draws, from the benchmark's JSON (one row per run):
  coupling_work_precision.png  error of the quantity of interest against wall time, one curve
                               per scheme (the points are the coupling steps dt_F), per problem
                               (and per DEM step dt_D where a problem has several); unstable runs
                               are left out
  coupling_stability.png       largest stable dt_F of each scheme against the plate-to-bed
                               mass ratio of problem (b); a scheme stable at no dt_F of the
                               grid is drawn below it
  coupling_iterations.png      iterations per coupling step of implicit Aitken and IQN-ILS
                               against dt_F (problem b, and a)
Rows of a later JSON file replace those of an earlier one for the same part, problem and DEM
step (a problem measured again, the others kept). Debian's python3 with python3-matplotlib (Agg
backend: no display needed).
"""
import json
import math
import os
import sys

from demfem_post.plots import pyplot_or_exit, save_figure

plt = pyplot_or_exit("plot_coupling_schemes.py")

# Problem (b): plate 0.2 x 0.2 x 0.002 m, 400 spheres of 19.9 mm at 7800 kg/m^3.
PLATE_VOLUME = 0.2 * 0.2 * 0.002
BED_MASS = 400 * 4.0 / 3.0 * math.pi * 0.00995**3 * 7800.0

STYLE = {
    "just_in_time": ("tab:blue", "o", "-"),
    "just_in_time+avg": ("tab:blue", "s", "--"),
    "predictive": ("tab:orange", "o", "-"),
    "predictive+avg": ("tab:orange", "s", "--"),
    "concurrent": ("tab:green", "^", "-"),
    "implicit-aitken": ("tab:purple", "D", "-"),
    "implicit-iqn": ("tab:red", "*", "-"),
}
TITLES = {
    "beam_drop": "(a) beam under a dropped slab: mid-span deflection",
    "beam_drop_elastic": "(a') the same, elastic contacts (restitution 1)",
    "plate_bed": "(b) light plate under a dense bed: centre deflection",
    "sheet_ci": "(c) sheet CI case: mean deflection at the measurement position",
}
# The rows of the work-precision figure. Problem (c) ("sheet" rows) is left out: the bench's
# measure for it, the mean over the last 0.1 s, is ill-conditioned (docs/coupling.md,
# "Problem (c)"; tools/sheet_scheme_errors.py gives the better ones).
WORK_PARTS = ("work",)


def finite(v):
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def work_precision(rows, out):
    # One panel per problem and DEM step (rows without dem_dt: older JSON, one dt_D).
    panels = []
    for p in TITLES:
        for d in sorted({r.get("dem_dt") or 0.0 for r in rows
                         if r["problem"] == p and r["part"] in WORK_PARTS}, reverse=True):
            panels.append((p, d))
    if not panels:
        return None
    ncol = min(len(panels), 3)
    nrow = (len(panels) + ncol - 1) // ncol
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.4 * ncol, 5.0 * nrow), squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax, (problem, dem_dt) in zip(axes.flat, panels):
        for scheme, (color, marker, ls) in STYLE.items():
            pts = sorted(
                (r["dt"], r["wall_median"], r["error"], r["wall_best"])
                for r in rows
                if r["part"] in WORK_PARTS and r["problem"] == problem and r["scheme"] == scheme
                and (r.get("dem_dt") or 0.0) == dem_dt
                and r["stable"] == 1 and finite(r["wall_best"]) and finite(r["error"])
                and r["error"] > 0)
            if not pts:
                continue
            # The best of the timed runs: on the shared machine the median of three scattered
            # by up to 10 x with the other jobs' load (both are in the JSON and docs).
            ax.plot([p[3] for p in pts], [p[2] for p in pts], color=color, marker=marker,
                    linestyle=ls, label=scheme)
            for dt, _, err, wall in pts:
                ax.annotate("%g" % dt, (wall, err), fontsize=6, color=color,
                            textcoords="offset points", xytext=(3, 2))
        ref = [r for r in rows if r["part"] == "reference" and r["problem"] == problem
               and finite(r["error"]) and r["error"] > 0]
        extrapolated = [r for r in ref if r["scheme"] == "extrapolated"]
        if extrapolated:
            ax.axhline(extrapolated[0]["error"], color="grey", linewidth=0.8, linestyle=":",
                       label="reference: error of the extrapolation (estimate)")
        elif ref:
            ax.axhline(ref[0]["error"], color="grey", linewidth=0.8, linestyle=":",
                       label="reference at dt_D vs 2 dt_D")
        for target in (1e-2, 1e-3, 1e-4):
            ax.axhline(target, color="black", linewidth=0.4, alpha=0.4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time of the run, s (best of the timed runs)")
        ax.set_ylabel("relative error of the mean deflection (last 0.1 s)" if problem == "sheet_ci"
                      else "largest deflection error / largest deflection")
        ax.set_title(TITLES[problem] + ("\n(dt_D = %g s)" % dem_dt if dem_dt else ""),
                     fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Work-precision (labels: dt_F in s; unstable runs left out)", fontsize=11)
    return save_figure(fig, os.path.join(out, "coupling_work_precision.png"), dpi=90)


def stability(rows, out):
    st = [r for r in rows if r["part"] == "stability"]
    if not st:
        return None
    densities = sorted({r["density"] for r in st})
    dts = sorted({r["dt"] for r in st})
    floor = min(dts) / 2.0
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    for i, (scheme, (color, marker, ls)) in enumerate(STYLE.items()):
        xs, ys = [], []
        for rho in densities:
            ok = [r["dt"] for r in st if r["scheme"] == scheme and r["density"] == rho
                  and r["stable"] == 1]
            xs.append(rho * PLATE_VOLUME / BED_MASS * (1.0 + 0.012 * (i - 3)))
            ys.append(max(ok) if ok else floor)
        ax.plot(xs, ys, color=color, marker=marker, linestyle=ls, label=scheme)
    ax.axhline(floor * 1.4, color="grey", linewidth=0.6, linestyle=":")
    ax.text(min(densities) * PLATE_VOLUME / BED_MASS, floor * 1.05,
            "stable at no dt_F >= %g s" % min(dts), fontsize=7, color="grey")
    for t, label in ((1e-5, "thesis: just-in-time 1e-5 s"), (1e-4, "thesis: predictive 1e-4 s")):
        ax.axhline(t, color="black", linewidth=0.5, alpha=0.5)
        ax.text(max(densities) * PLATE_VOLUME / BED_MASS, t * 1.08, label, fontsize=7,
                ha="right")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("plate mass / bed mass (plate density varied)")
    ax.set_ylabel("largest stable dt_F, s")
    ax.set_title("Stability map, problem (b): light plate under a dense bed", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return save_figure(fig, os.path.join(out, "coupling_stability.png"), dpi=90)


def iterations(rows, out):
    it = [r for r in rows if r["part"] == "work" and r["scheme"].startswith("implicit")]
    if not it:
        return None
    # Each problem at its case's DEM step (the largest of its rows).
    case_dt = {}
    for r in it:
        case_dt[r["problem"]] = max(case_dt.get(r["problem"], 0.0), r.get("dem_dt") or 0.0)
    it = [r for r in it if (r.get("dem_dt") or 0.0) == case_dt[r["problem"]]]
    problems = [p for p in TITLES if any(r["problem"] == p for r in it)]
    fig, axes = plt.subplots(1, len(problems), figsize=(5.5 * len(problems), 4.2), squeeze=False)
    for ax, problem in zip(axes[0], problems):
        for scheme in ("implicit-aitken", "implicit-iqn"):
            color, marker, _ = STYLE[scheme]
            pts = sorted((r["dt"], r["iterations_mean"], r["iterations_max"]) for r in it
                         if r["problem"] == problem and r["scheme"] == scheme
                         and finite(r["iterations_mean"]) and r["exit"] == 0)
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], color=color, marker=marker,
                        label=scheme + " (mean)")
                ax.plot([p[0] for p in pts], [p[2] for p in pts], color=color, marker=marker,
                        linestyle=":", alpha=0.6, label=scheme + " (most in a step)")
        ax.axhline(5, color="black", linewidth=0.5, alpha=0.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("dt_F, s")
        ax.set_ylabel("iterations per coupling step")
        ax.set_title(TITLES[problem].split(":")[0], fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, os.path.join(out, "coupling_iterations.png"), dpi=90)


def main(argv):
    if any(a in ("-h", "--help") for a in argv[1:]):  # not a folder or file named --help
        print(__doc__)
        return 0
    if len(argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    # Several JSON files (the parts of the benchmark run separately) are drawn together; the
    # last argument is the output folder when it is not a JSON file.
    files = [a for a in argv[1:] if a.endswith(".json")]
    out = argv[-1] if not argv[-1].endswith(".json") else os.path.dirname(os.path.abspath(argv[1]))
    os.makedirs(out, exist_ok=True)
    rows = []
    for name in files:
        with open(name) as f:
            new = json.load(f)["rows"]
        # An older file's row without dem_dt (one DEM step) goes with any of its problem.
        measured = {(r["part"], r["problem"], r.get("dem_dt")) for r in new}
        problems = {(r["part"], r["problem"]) for r in new}
        rows = [r for r in rows
                if (r["part"], r["problem"], r.get("dem_dt")) not in measured
                and not (r.get("dem_dt") is None and (r["part"], r["problem"]) in problems)] + new
    for path in (work_precision(rows, out), stability(rows, out), iterations(rows, out)):
        if path:
            print("wrote", path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
