"""Plots in the thesis's style (Ullrich 2022, ch. 6: "the mean over 10 repetitions with the
standard deviation as pale band around the mean"): for a time series, one mean curve with a
pale +/- sd band per setting; for a scalar quantity, mean +/- sd against the first numeric
parameter (one line per combination of the other parameters), the members as small dots.
matplotlib with the Agg backend (no display needed); PNG files, atomically replaced."""

import math
import os
from pathlib import Path

from sweep import scene_keys


def _label(plan, values):
    parts = []
    for p in plan.parameters:
        v = values[p["name"]]
        text = f"{v:g}" if isinstance(v, float) else (scene_keys.toml_value(v)
                                                     if not isinstance(v, str) else v)
        parts.append(f"{p['name']} = {text}{' ' + p['unit'] if p['unit'] else ''}")
    return ", ".join(parts) if parts else "all members"


def _save(fig, path):
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    fig.savefig(tmp, dpi=120)
    os.replace(tmp, path)


def _axis_label(name, unit):
    return f"{name} [{unit}]" if unit else name


def draw(spec, plan, settings, summary, series_stats, folder):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for q in spec.quantities:
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        if q.kind == "series":
            for k, (si, (grid, mean, sd, n)) in enumerate(sorted(series_stats[q.name].items())):
                c = colours[k % len(colours)]
                ax.plot(grid, mean, color=c, lw=1.4,
                        label=f"{_label(plan, settings[si][0].values)} (n = {n})")
                if n > 1:
                    ax.fill_between(grid, [m - s for m, s in zip(mean, sd)],
                                    [m + s for m, s in zip(mean, sd)], color=c, alpha=0.25, lw=0)
            ax.set_xlabel(_axis_label(q.time_column, "s" if q.time_column == "time" else ""))
            ax.set_ylabel(_axis_label(q.name, q.unit))
            ax.set_title(f"{plan.name}: {q.name}, mean ± sd")
        else:
            _scalar(ax, plan, settings, summary, q, colours)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
        fig.tight_layout()
        path = folder / f"{q.name}.png"
        _save(fig, path)
        plt.close(fig)
        written.append(path)
    return written


def _scalar(ax, plan, settings, summary, q, colours):
    params = plan.parameters
    numeric = [i for i, p in enumerate(params)
               if all(isinstance(v, (int, float)) and not isinstance(v, bool)
                      for v in p["values"][0])]
    ax.set_ylabel(_axis_label(q.name, q.unit))
    ax.set_title(f"{plan.name}: {q.name}, mean ± sd")
    if numeric:
        xi = numeric[0]
        xp = params[xi]
        groups = {}
        for si, ms in sorted(settings.items()):
            rest = tuple((p["name"], scene_keys.toml_value(ms[0].values[p["name"]]))
                         for j, p in enumerate(params) if j != xi)
            groups.setdefault(rest, []).append(si)
        for k, (rest, sis) in enumerate(groups.items()):
            c = colours[k % len(colours)]
            xs, mu, sd = [], [], []
            for si in sis:
                n, mean, s, _, _, vals = summary[si][q.name]
                if n == 0:
                    continue
                x = settings[si][0].values[xp["name"]]
                xs.append(x)
                mu.append(mean)
                sd.append(0.0 if math.isnan(s) else s)
                ax.plot([x] * n, vals, ".", color=c, ms=3, alpha=0.5)
            label = ", ".join(f"{n} = {v}" for n, v in rest) or None
            ax.errorbar(xs, mu, yerr=sd, color=c, marker="o", ms=4, capsize=4, lw=1.2,
                        label=label)
        ax.set_xlabel(_axis_label(xp["name"], xp["unit"]))
    else:
        xs, mu, sd, ticks = [], [], [], []
        for si, ms in sorted(settings.items()):
            n, mean, s, _, _, vals = summary[si][q.name]
            if n == 0:
                continue
            ax.plot([si] * n, vals, ".", color=colours[0], ms=3, alpha=0.5)
            xs.append(si)
            mu.append(mean)
            sd.append(0.0 if math.isnan(s) else s)
            ticks.append(_label(plan, ms[0].values))
        ax.errorbar(xs, mu, yerr=sd, color=colours[0], marker="o", ms=4, capsize=4, lw=0,
                    elinewidth=1.2)
        ax.set_xticks(xs)
        ax.set_xticklabels(ticks, rotation=20, ha="right", fontsize=8)
        ax.set_xlabel("setting")
