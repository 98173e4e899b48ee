#!/usr/bin/python3
"""Plots and key figures of a steel-sheet run (thesis ch. 5, cases/sheet*.toml).

usage: tools/sheet_report.py OUTPUT_DIR [--probe lmp] [--flow-steady 0.3,1.5] [--tail 2.0]
                             [--deflection-steady 0.6,1.6] [--smooth 0.2]

Reads OUTPUT_DIR/sensor_outflow.csv (mass flow through the plane under the flaps, eq. 2.26),
OUTPUT_DIR/fem_monitor.csv (probe displacements, total interface force) and, when present,
OUTPUT_DIR/coupling.csv, and writes into OUTPUT_DIR:
  mass_flow.png      rate (kg/s) and mass that crossed (kg) against time
  deflection.png     deflection of the probe (mm, negative = down) against time, raw and
                     smoothed over --smooth seconds (about one period of the loaded sheet),
                     the other probes, and the total force on the sheet (N)
  sheet_report.txt   the key points below, in words and numbers
  sheet_report.json  the same, for scripts and tests
Key points. Mass flow: the peak (time, rate); the near-constant phase (mean, standard
deviation, min and max of the rate over --flow-steady); the tail (mean rate over 0.5 s
windows from --tail on, and when 90 / 95 / 99 % of the final mass had crossed).
Deflection of the probe (uz): the peak (most downward value, time); the back-bending after
it (the highest value within 0.25 s after the peak, time, and the rise); the steady phase
(mean and standard deviation of the raw and smoothed deflection over --deflection-steady);
the late back-bending (when the smoothed deflection, after the steady window, first comes
back to half the steady mean, and the mean over the last 0.2 s). Windows that the run does
not reach are reported as missing (null). Exit status 2 on a missing file or column.
"""

import argparse
import json
import os
import sys

from demfem_post import read_csv, tool_errors
from demfem_post.plots import pyplot, save_figure
from demfem_post.windows import moving_average, stats, window


def flow_points(t, rate, mass, steady, tail):
    i = max(range(len(rate)), key=lambda k: rate[k])
    res = {"peak": {"time": t[i], "rate": rate[i]},
           "steady": None, "tail": [], "final_mass": mass[-1], "end_time": t[-1]}
    if t[-1] >= steady[1] - 1e-6:
        s = stats(window(t, rate, steady[0], steady[1]))
        if s:
            s.update({"from": steady[0], "to": steady[1]})
            res["steady"] = s
    lo = tail
    while lo + 0.5 <= t[-1] + 1e-9:
        s = stats(window(t, rate, lo + 1e-9, lo + 0.5))
        res["tail"].append({"from": lo, "to": lo + 0.5, "mean_rate": s["mean"] if s else None})
        lo += 0.5
    for q in (0.9, 0.95, 0.99):
        k = next((k for k, m in enumerate(mass) if m >= q * mass[-1]), None)
        res[f"time_{int(q * 100)}pct"] = t[k] if k is not None and mass[-1] > 0 else None
    return res


def deflection_points(t, uz, smooth, steady):
    i = min(range(len(uz)), key=lambda k: uz[k])
    res = {"peak": {"time": t[i], "uz": uz[i]}, "back_bending": None, "steady": None,
           "late_back_bending": None, "final": None, "end_time": t[-1]}
    after = [k for k in range(i, len(t)) if t[k] <= t[i] + 0.25]
    j = max(after, key=lambda k: uz[k])
    res["back_bending"] = {"time": t[j], "uz": uz[j], "rise": uz[j] - uz[i],
                           "duration": t[j] - t[i]}
    if t[-1] >= steady[1] - 1e-6:
        raw = stats(window(t, uz, steady[0], steady[1]))
        sm = stats(window(t, smooth, steady[0], steady[1]))
        res["steady"] = {"from": steady[0], "to": steady[1], "mean": raw["mean"],
                         "std": raw["std"], "smoothed_min": sm["min"], "smoothed_max": sm["max"]}
        half = 0.5 * raw["mean"]
        k = next((k for k in range(len(t)) if t[k] > steady[1] and smooth[k] > half), None)
        if k is not None:
            res["late_back_bending"] = {"time": t[k], "smoothed_uz": smooth[k],
                                        "threshold": half}
    last = stats(window(t, uz, t[-1] - 0.2, t[-1]))
    res["final"] = last["mean"] if last else None
    return res


def fmt(x, scale=1.0, digits=3):
    return "n/a" if x is None else f"{x * scale:.{digits}f}"


def report_text(out_dir, flow, defl, force, probe):
    L = [f"Steel sheet under grain flow: {out_dir}", ""]
    L.append("Mass flow through the plane under the flaps (eq. 2.26):")
    L.append(f"  peak {fmt(flow['peak']['rate'])} kg/s at t = {fmt(flow['peak']['time'])} s")
    s = flow["steady"]
    if s:
        L.append(f"  near-constant phase {s['from']}-{s['to']} s: mean {fmt(s['mean'])} kg/s, "
                 f"sd {fmt(s['std'])}, range {fmt(s['min'])}-{fmt(s['max'])} kg/s")
    else:
        L.append("  near-constant phase: the run ends before the window ends")
    for w in flow["tail"]:
        L.append(f"  tail {w['from']:.1f}-{w['to']:.1f} s: mean {fmt(w['mean_rate'])} kg/s")
    L.append(f"  mass crossed {fmt(flow['final_mass'])} kg by t = {fmt(flow['end_time'])} s; "
             f"90/95/99 % of it by {fmt(flow['time_90pct'])}/{fmt(flow['time_95pct'])}/"
             f"{fmt(flow['time_99pct'])} s")
    L.append("")
    L.append(f"Deflection at probe '{probe}' (uz, mm; negative = down):")
    L.append(f"  peak {fmt(defl['peak']['uz'], 1e3, 2)} mm at t = {fmt(defl['peak']['time'])} s")
    b = defl["back_bending"]
    L.append(f"  back-bending to {fmt(b['uz'], 1e3, 2)} mm at t = {fmt(b['time'])} s "
             f"(+{fmt(b['rise'], 1e3, 2)} mm in {fmt(b['duration'])} s)")
    s = defl["steady"]
    if s:
        L.append(f"  steady phase {s['from']}-{s['to']} s: mean {fmt(s['mean'], 1e3, 2)} mm, "
                 f"sd {fmt(s['std'], 1e3, 2)} mm (smoothed {fmt(s['smoothed_min'], 1e3, 2)} to "
                 f"{fmt(s['smoothed_max'], 1e3, 2)} mm)")
    lb = defl["late_back_bending"]
    if lb:
        L.append(f"  late back-bending: the smoothed deflection is back at half the steady mean "
                 f"({fmt(lb['threshold'], 1e3, 2)} mm) at t = {fmt(lb['time'])} s")
    else:
        L.append("  late back-bending: not within the run")
    L.append(f"  mean over the last 0.2 s: {fmt(defl['final'], 1e3, 2)} mm")
    if force:
        L.append("")
        L.append(f"Total force on the sheet (z, N): most downward {fmt(force['min'])} N, "
                 f"mean over the steady window {fmt(force.get('steady_mean'))} N")
    return "\n".join(L) + "\n"


def plots(out_dir, ft, rate, mass, flow, mt, series, probe, smooth, fz, defl):
    plt = pyplot()

    fig, ax = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    ax[0].step(ft, rate, where="pre", lw=1.2, color="tab:red")
    ax[0].set_ylabel("mass flow rate (kg/s)")
    ax[0].plot([flow["peak"]["time"]], [flow["peak"]["rate"]], "k^")
    if flow["steady"]:
        s = flow["steady"]
        ax[0].axvspan(s["from"], s["to"], color="0.9")
        ax[0].axhline(s["mean"], color="0.4", lw=0.8, ls="--")
    ax[1].plot(ft, mass, color="tab:blue")
    ax[1].set_ylabel("mass crossed (kg)")
    ax[1].set_xlabel("time (s)")
    for a in ax:
        a.grid(True, alpha=0.3)
    fig.suptitle("Mass flow under the flaps (eq. 2.26)")
    save_figure(fig, os.path.join(out_dir, "mass_flow.png"))

    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True,
                           gridspec_kw={"height_ratios": [2, 1]})
    for name, uz in series.items():
        if name != probe:
            ax[0].plot(mt, [1e3 * u for u in uz], lw=0.6, alpha=0.5, label=name)
    ax[0].plot(mt, [1e3 * u for u in series[probe]], lw=0.8, color="tab:red", label=probe)
    ax[0].plot(mt, [1e3 * u for u in smooth], lw=1.6, color="k", label=f"{probe}, smoothed")
    if defl["steady"]:
        ax[0].axvspan(defl["steady"]["from"], defl["steady"]["to"], color="0.92")
    ax[0].set_ylabel("deflection uz (mm)")
    ax[0].legend(loc="lower right", fontsize=8)
    ax[1].plot(mt, fz, lw=0.5, color="tab:green")
    ax[1].set_ylabel("force on sheet, z (N)")
    ax[1].set_xlabel("time (s)")
    for a in ax:
        a.grid(True, alpha=0.3)
    fig.suptitle("Deflection of the steel sheet (cf. thesis fig. 5.4)")
    save_figure(fig, os.path.join(out_dir, "deflection.png"))


def pair(text):
    a, b = (float(x) for x in text.split(","))
    return (a, b)


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("output_dir")
    p.add_argument("--probe", default="lmp")
    p.add_argument("--flow-steady", type=pair, default=(0.3, 1.5))
    p.add_argument("--tail", type=float, default=2.0)
    p.add_argument("--deflection-steady", type=pair, default=None,
                   help="default: --flow-steady shifted by the fall time, 0.27 s")
    p.add_argument("--smooth", type=float, default=0.2)
    a = p.parse_args(argv)
    d = a.output_dir
    dsteady = a.deflection_steady or (a.flow_steady[0] + 0.27, a.flow_steady[1] + 0.27)
    with tool_errors("sheet_report.py"):
        fpath = os.path.join(d, "sensor_outflow.csv")
        fc = read_csv(fpath)
        ft, rate, mass = fc.column("time"), fc.column("mass_flow"), fc.column("mass_crossed")
        mpath = os.path.join(d, "fem_monitor.csv")
        mc = read_csv(mpath)
        mt = mc.column("time")
        series = {h[:-3]: v for h, v in mc.lists().items() if h.endswith("_uz")}
        if a.probe not in series:
            raise KeyError(f"{mpath}: no probe '{a.probe}' (probes: {', '.join(series)})")
        fz = mc.column("force_z")
        uz = series[a.probe]
        smooth = moving_average(mt, uz, a.smooth)
        flow = flow_points(ft, rate, mass, a.flow_steady, a.tail)
        defl = deflection_points(mt, uz, smooth, dsteady)
        force = {"min": min(fz)}
        fs = stats(window(mt, fz, *dsteady)) if mt[-1] >= dsteady[1] - 1e-6 else None
        force["steady_mean"] = fs["mean"] if fs else None
        result = {"probe": a.probe, "mass_flow": flow, "deflection": defl, "force_z": force}
        with open(os.path.join(d, "sheet_report.json"), "w") as f:
            json.dump(result, f, indent=1)
        text = report_text(d, flow, defl, force, a.probe)
        with open(os.path.join(d, "sheet_report.txt"), "w") as f:
            f.write(text)
        print(text, end="")
        plots(d, ft, rate, mass, flow, mt, series, a.probe, smooth, fz, defl)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
