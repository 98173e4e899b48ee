"""The sleeper studies' tables and figure (`python3 -m studies sleeper collect STUDY ...`,
tools/studies/sleeper.py): each done member's settlement since the load start against the
reference time, and its scalars from sleeper_report.json; mean and sd over the seeds of each
setting; for the dt and freeze studies, each setting against the smallest."""

import csv
import json
import math
import os
import sys

from demfem_post import load_scene, read_csv
from demfem_post.plots import pyplot_or_exit
from studies.sleeper import LOAD, SEAT_KEYS, STUDIES
from studies.sweep_study import DONE, members_of
from sweep import scene_keys
from sweep.stats import summarise

# the table's columns (those the members have), in this order
SHOW = ["seating_mm", "peak_mm", "cycle1_mm", "last_cycle_mm", "final_mm",
        "held_under_load_mm", "balance_pct", "cell1_kPa", "cell2_kPa", "cell3_kPa",
        "cell4_kPa", "cell5_kPa", "Z_all_rocks", "Z_under_sleeper", "phi_all_rocks",
        "strain_centre_hold_ue", "max_principal_strain_ue", "wall_s"]
# the studies whose settings are compared with their smallest (the smallest step, no
# freezing), and the figures compared
COMPARED_STUDIES = ("dt", "freeze")
COMPARED = ["seating_mm", "held_under_load_mm", "held_mm", "balance_pct", "cell1_kPa",
            "cell2_kPa", "cell3_kPa", "cell4_kPa", "cell5_kPa", "Z_all_rocks",
            "Z_under_sleeper", "Z_packing_upper", "phi_all_rocks", "max_principal_strain_ue"]


def fmt(v):
    return f"{v:g}" if isinstance(v, float) else str(v)


def minima_of(rep):
    """The settlement since the load start (mm) at each cycle's minimum load (0: the first
    ramp's end, at the peak), from a sleeper_report.json."""
    s0 = rep["settlement_at_load_start_mm"]
    return [c["settlement_mm"] - s0 for c in rep.get("cycles", [])]


def report_scalars(rep):
    """The figures of one member's sleeper_report.json."""
    hold = rep.get("hold", {})
    s0 = rep["settlement_at_load_start_mm"]
    mins = minima_of(rep)
    out = {"seating_mm": s0, "final_mm": rep["settlement_final_mm"] - s0,
           "tilt_final_mm": rep.get("tilt_final_mm")}
    if len(mins) > 1:
        out.update(peak_mm=mins[0], cycle1_mm=mins[1], last_cycle_mm=mins[-1])
    if "held_settlement_mm" in hold:
        out["held_mm"] = hold["held_settlement_mm"]
        out["held_under_load_mm"] = hold["held_settlement_under_load_mm"]
    if "balance_rel" in hold:
        out["balance_pct"] = 100.0 * hold["balance_rel"]
    for name, p in hold.get("cell_pressure_kPa", {}).items():
        out[f"{name}_kPa"] = p
    for label, e in hold.get("strain", {}).items():
        out[f"strain_{label}_hold_ue"] = 1e6 * e
    if "max_principal_strain" in rep:
        out["max_principal_strain_ue"] = 1e6 * rep["max_principal_strain"]
    for name in ("all_rocks", "packing_lower", "packing_upper", "under_sleeper"):
        key = name if name.startswith("packing") else "packing_" + name
        if key in rep:  # at the run's end: the bed under the held load
            out[f"Z_{name}"] = rep[key]["last"]["coordination"]
            out[f"phi_{name}"] = rep[key]["last"]["solid_fraction"]
    return out


def member_series(member):
    """(reference time, settlement since the load start in mm) of a done member."""
    sc = load_scene(str(LOAD), member.overrides)
    amp = scene_keys.get(sc, SEAT_KEYS[0])
    ts, start = amp.get("time_scale", 1.0), amp.get("start_time", 0.0)
    mon = read_csv(os.path.join(member.folder, "fem_monitor.csv"))
    t = mon.column("time")
    uz = [mon.column(h) for h in mon if h.startswith("b") and h.endswith("_uz")]
    s = [1e3 * sum(u[i] for u in uz) / len(uz) for i in range(len(t))]
    i0 = min(range(len(t)), key=lambda j: abs(t[j] - start))
    return [(x - start) / ts for x in t], [x - s[i0] for x in s]


def _on_grid(grid, tau, rel):
    j, y = 0, []
    for x in grid:
        while j + 1 < len(tau) - 1 and tau[j + 1] < x:
            j += 1
        x0, x1 = tau[j], tau[j + 1]
        w = 0.0 if x1 == x0 else min(1.0, max(0.0, (x - x0) / (x1 - x0)))
        y.append(rel[j] + w * (rel[j + 1] - rel[j]))
    return y


def gather(out, study):
    """{setting value: [(seed, member, scalars)]} of the done members with a report."""
    by_value = {}
    for member, state, rec in members_of(out, study):
        path = os.path.join(member.folder, "sleeper_report.json")
        if state != DONE or not os.path.exists(path):
            continue
        with open(path) as f:
            scal = report_scalars(json.load(f))
        scal["wall_s"] = rec.get("run_time", math.nan)
        by_value.setdefault(member.values[study], []).append(
            (member.values["seed"], member, scal))
    return by_value


def summary_rows(by_value):
    rows = []
    for v in sorted(by_value):
        recs = by_value[v]
        row = {"setting": fmt(v), "n": len(recs), "seeds": " ".join(str(s) for s, _, _ in recs)}
        for k in dict.fromkeys(k for r in recs for k in r[2]):
            vals = [r[2].get(k) for r in recs]
            vals = [x for x in vals if x is not None and math.isfinite(x)]
            _, m, sd, _, _ = summarise(vals)
            row[k + "_mean"], row[k + "_sd"] = m, sd
        rows.append(row)
    return rows


def against_reference(by_value):
    """The dt and freeze studies: for each setting and figure, the mean's difference from
    that of the reference (the smallest setting: the smallest step, freezing off), and the
    largest difference of one seed's member from the same seed's reference member (same
    bed), beside the reference's sd over the seeds."""
    ref_v = min(by_value)
    ref = {s: scal for s, _, scal in by_value[ref_v]}
    rows = []
    for v in sorted(by_value):
        row = {"setting": v}
        own = {s: scal for s, _, scal in by_value[v]}
        for k in COMPARED:
            r = [ref[s][k] for s in ref if k in ref[s]]
            mine = [own[s][k] for s in own if k in own[s]]
            if len(r) < 2 or not mine:
                continue
            _, m_ref, sd_ref, _, _ = summarise(r)
            _, m, _, _, _ = summarise(mine)
            paired = [own[s][k] - ref[s][k] for s in own if s in ref and k in own[s]]
            row[k] = {"mean": m, "mean_diff": m - m_ref, "ref_sd": sd_ref,
                      "mean_diff_over_sd": (m - m_ref) / sd_ref if sd_ref > 0 else math.nan,
                      "largest_paired_diff": max(paired, key=abs) if paired else math.nan}
        rows.append(row)
    return rows


def write_summary(folder, study, rows, comparison):
    fields = list(rows[0])
    path = os.path.join(folder, "study_summary.csv")
    with open(path + ".part", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in rows:
            w.writerow({k: (repr(x) if isinstance(x, float) else x) for k, x in r.items()})
    os.replace(path + ".part", path)
    path = os.path.join(folder, "study_summary.json")
    with open(path + ".part", "w") as f:
        json.dump({"study": study, "parameter": STUDIES[study].label, "rows": rows,
                   "against_reference": comparison}, f, indent=1)
    os.replace(path + ".part", path)


def print_table(study, rows, comparison):
    print(f"\n{study} ({STUDIES[study].label}): mean +- sd over the seeds; settlement since "
          "the load start (mm, negative down), force balance of the hold (%), cell pressures "
          "in the hold (kPa), coordination Z and solid fraction phi at the end, strain "
          "(microstrain), wall time of the member (s)")
    show = [k for k in SHOW if k + "_mean" in rows[0]]
    print("setting  n  " + "  ".join(f"{k:>18}" for k in show))
    for r in rows:
        print(f"{r['setting']:>7} {r['n']:2d}  " + "  ".join(
            f"{r[k + '_mean']:9.4g} ±{r[k + '_sd']:8.2g}" for k in show))
    if comparison:
        print(f"\nagainst {fmt(min(r['setting'] for r in comparison))}: (mean - its mean) / "
              "its sd over the seeds; [largest difference of one seed from the same bed's "
              "member there]")
        keys = [k for k in COMPARED if any(k in r for r in comparison)]
        for r in comparison:
            print(f"{fmt(r['setting']):>7}  " + "  ".join(
                f"{k}: {r[k]['mean_diff_over_sd']:+.2f} [{r[k]['largest_paired_diff']:+.3g}]"
                for k in keys if k in r))


def cycle_minima(member):
    """minima_of the member's sleeper_report.json."""
    with open(os.path.join(member.folder, "sleeper_report.json")) as f:
        return minima_of(json.load(f))


def plot(study, by_value, figures):
    """The settlement since the load start against the reference time, mean with a pale
    +- sd band per setting; beside it the settlement at the cycles' minima, mean +- sd."""
    plt = pyplot_or_exit("sleeper_study.py")
    label = STUDIES[study].label
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5),
                                  gridspec_kw={"width_ratios": [2.2, 1]})
    for v in sorted(by_value):
        series = [member_series(m) for _, m, _ in by_value[v]]
        lo = max(0.0, max(s[0][0] for s in series))
        hi = min(s[0][-1] for s in series)
        grid = [x for x in series[0][0] if lo <= x <= hi]
        ys = [_on_grid(grid, tau, rel) for tau, rel in series]
        ms = [summarise([y[i] for y in ys]) for i in range(len(grid))]
        m = [x[1] for x in ms]
        sd = [0.0 if math.isnan(x[2]) else x[2] for x in ms]
        line, = ax.plot(grid, m, lw=1.2, label=f"{label} {fmt(v)} (n = {len(series)})")
        ax.fill_between(grid, [a - b for a, b in zip(m, sd)], [a + b for a, b in zip(m, sd)],
                        color=line.get_color(), alpha=0.2, lw=0)
        minima = [cycle_minima(mb) for _, mb, _ in by_value[v]]
        n = min(len(x) for x in minima)
        at = [summarise([x[k] for x in minima]) for k in range(n)]
        ax2.errorbar(range(n), [x[1] for x in at],
                     yerr=[0.0 if math.isnan(x[2]) else x[2] for x in at], marker="o",
                     capsize=3, color=line.get_color(), label=fmt(v))
    ax.set_xlabel("reference time (t - load start) / time scale (s)")
    ax.set_ylabel("settlement since the load start (mm)")
    ax.set_title(f"sleeper (small chain): {label}, mean ± sd over seeds", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, lw=0.3)
    ax2.set_xlabel("cycle (0: the first ramp's end, at the peak)")
    ax2.set_ylabel("settlement at the cycle minimum (mm)")
    ax2.set_title("at the cycles' minimum load, mean ± sd", fontsize=10)
    ax2.legend(fontsize=8, title=label, title_fontsize=8)
    ax2.grid(True, lw=0.3)
    fig.tight_layout()
    os.makedirs(figures, exist_ok=True)
    png = os.path.join(figures, f"sleeper_study_{study}.png")
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def collect(a):
    for study in a.studies:
        folder = os.path.join(a.out, study)
        if not os.path.exists(os.path.join(folder, "plan.json")):
            print(f"{study}: no sweep in {folder} (run it first)", file=sys.stderr)
            return 1
        by_value = gather(a.out, study)
        if not by_value:
            print(f"{study}: no finished members in {folder}", file=sys.stderr)
            return 1
        rows = summary_rows(by_value)
        comparison = against_reference(by_value) if study in COMPARED_STUDIES else []
        write_summary(folder, study, rows, comparison)
        print_table(study, rows, comparison)
        png = plot(study, by_value, a.figures)
        print(f"wrote {os.path.join(folder, 'study_summary.csv')}, {png}")
    return 0
