"""Collecting quantities from the members' CSV output and aggregating them per setting.

A quantity is a column of a CSV file in the member's output folder, taken against its time
column:
* at = T, method "linear": linear interpolation between the two rows around T (a row at T
  exactly gives its value); method "nearest": the row nearest to T (the earlier on a tie).
  T outside the series' time span is an error.
* reduce = "final": the last row. "max", "min": over the rows with t in the window (fixed
  times, or with `last` = D the member's own last D seconds: members that run for different
  times, such as a time-scale study's).
  "mean": the time average over the window (clipped to the series' span) by the trapezoidal
  rule, the window's ends interpolated linearly. "series": the rows in the window, kept as a
  time series (plotted over time; not a column of members.csv).
* relative_to = T (with any of the above): the column's value at T (linear interpolation) is
  subtracted from every row first, so the quantity is the change since T (a sleeper's
  settlement under the load, counted from its seated position rather than from the mesh).
Outputs (atomically replaced): members.csv (one row per member), summary.csv (per setting:
n, failed, mean, sd and the Student-t 95 % interval of each scalar quantity), and for each
series quantity series_<name>.csv (per setting mean and sd over time)."""

import csv
import importlib.util
import io
import math
import os
from pathlib import Path

from sweep import records, scene_keys
from sweep.stats import summarise
from sweep.sweep_file import SweepError


def read_series(path, time_column, column, where, member_id):
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        raise SweepError(f"{where}: member {member_id}: cannot read {path} ({e.strerror})")
    if len(rows) < 2:
        raise SweepError(f"{where}: member {member_id}: {path} has no data rows")
    header = [h.strip() for h in rows[0]]
    for c in (time_column, column):
        if c not in header:
            raise SweepError(f"{where}: member {member_id}: {path} has no column '{c}' "
                             f"(columns: {', '.join(header)})")
    it, ic = header.index(time_column), header.index(column)
    t, v = [], []
    for no, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise SweepError(f"{where}: member {member_id}: {path}:{no}: {len(row)} fields, the "
                             f"header has {len(header)}")
        try:
            ti, vi = float(row[it]), float(row[ic])
        except ValueError:
            raise SweepError(f"{where}: member {member_id}: {path}:{no}: not a number in "
                             f"'{time_column}' or '{column}'")
        if t and ti < t[-1]:
            raise SweepError(f"{where}: member {member_id}: {path}:{no}: time goes backwards "
                             f"({ti} after {t[-1]})")
        t.append(ti)
        v.append(vi)
    return t, v


def interpolate(t, v, at):
    """Linear interpolation of the series at `at` (within [t[0], t[-1]])."""
    lo, hi = 0, len(t) - 1
    if at <= t[0]:
        return v[0]
    if at >= t[-1]:
        return v[-1]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if t[mid] <= at:
            lo = mid
        else:
            hi = mid
    if t[lo] == at:
        return v[lo]
    if t[hi] == t[lo]:
        return v[hi]
    w = (at - t[lo]) / (t[hi] - t[lo])
    return v[lo] + w * (v[hi] - v[lo])


def extract(q, t, v, where, member_id):
    """The value of quantity `q` from one member's series (a float, or (t, v) for series)."""
    if not math.isnan(q.relative_to):  # a change since then: the value at relative_to is zero
        if not t[0] <= q.relative_to <= t[-1]:
            raise SweepError(f"{where}: relative_to = {q.relative_to:g} s is outside member "
                             f"{member_id}'s series [{t[0]:g}, {t[-1]:g}] s ({q.file})")
        v0 = interpolate(t, v, q.relative_to)
        v = [x - v0 for x in v]
    if q.kind == "final":
        return v[-1]
    if q.kind == "at":
        if not t[0] <= q.at <= t[-1]:
            raise SweepError(f"{where}: at = {q.at:g} s is outside member {member_id}'s series "
                             f"[{t[0]:g}, {t[-1]:g}] s ({q.file})")
        if q.method == "nearest":
            best = min(range(len(t)), key=lambda i: (abs(t[i] - q.at), i))
            return v[best]
        return interpolate(t, v, q.at)
    t0, t1 = q.window
    if not math.isnan(q.last):  # members of another duration each take their own end
        t0, t1 = t[-1] - q.last, t[-1]
    idx = [i for i in range(len(t)) if t0 <= t[i] <= t1]
    if q.kind == "series":
        if not idx:
            raise SweepError(f"{where}: member {member_id}: no row of {q.file} in the window")
        return [t[i] for i in idx], [v[i] for i in idx]
    if q.kind in ("max", "min"):
        if not idx:
            raise SweepError(f"{where}: member {member_id}: no row of {q.file} with t in "
                             f"[{t0:g}, {t1:g}] s")
        vals = [v[i] for i in idx]
        return max(vals) if q.kind == "max" else min(vals)
    # mean: trapezoidal time average over the window clipped to the series' span.
    a, b = max(t0, t[0]), min(t1, t[-1])
    if a > b:
        raise SweepError(f"{where}: member {member_id}: the window [{t0:g}, {t1:g}] s and the "
                         f"series [{t[0]:g}, {t[-1]:g}] s of {q.file} do not overlap")
    if a == b:
        return interpolate(t, v, a)
    pts = [(a, interpolate(t, v, a))] + [(t[i], v[i]) for i in range(len(t)) if a < t[i] < b] \
        + [(b, interpolate(t, v, b))]
    area = math.fsum(0.5 * (pts[k + 1][1] + pts[k][1]) * (pts[k + 1][0] - pts[k][0])
                     for k in range(len(pts) - 1))
    return area / (b - a)


def cell(v):
    """A CSV cell: numbers in their shortest exact form, other values as TOML text."""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (bool, list, dict)):
        return scene_keys.toml_value(v)
    return str(v)


def write_csv_atomic(path, header, rows):
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        w.writerow([cell(x) for x in r])
    tmp = Path(path).with_name(f".{Path(path).name}.{os.getpid()}.tmp")
    tmp.write_text(buf.getvalue())
    os.replace(tmp, path)


def collect(spec, plan, states, log=print, plots=True):
    """Writes members.csv, summary.csv, series_<q>.csv and the plots; returns the paths."""
    out = Path(plan.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    pnames = [p["name"] for p in plan.parameters]
    scalars = [q for q in spec.quantities if q.kind != "series"]
    series = [q for q in spec.quantities if q.kind == "series"]
    values = {}   # member id -> {quantity name -> value}
    by_id = {m.id: (m, s, r) for (m, s, r, _) in states}
    for m, state, rec, _ in states:
        if state != records.DONE:
            continue
        vals = {}
        for q in spec.quantities:
            # a stage's quantity lies in that stage's folder of the member
            t, v = read_series(Path(m.folder) / q.stage / q.file, q.time_column, q.column,
                               q.where, m.id)
            vals[q.name] = extract(q, t, v, q.where, m.id)
        values[m.id] = vals

    # With stages, each stage's state and run time (s) besides the member's (their sum).
    stage_names = [st["name"] for st in plan.stages]
    header = ["member", "setting"] + pnames + ["seed"] + [q.name for q in scalars] + \
        ["status", "attempts", "run_time"] + \
        [f"{n}_{c}" for n in stage_names for c in ("status", "run_time")]
    rows = []
    for m, state, rec, _ in states:
        vals = values.get(m.id, {})
        per_stage = []
        for n in stage_names:
            st = (rec.get("stages") or {}).get(n) or {}
            per_stage += [st.get("state", "new"), st.get("run_time", math.nan)]
        rows.append([m.id, m.setting] + [m.values[p] for p in pnames] + [m.seed] +
                    [vals.get(q.name, math.nan) for q in scalars] +
                    [state, len(rec.get("attempts", [])), rec.get("run_time", math.nan)] +
                    per_stage)
    write_csv_atomic(out / "members.csv", header, rows)

    settings = {}
    for m in plan.members:
        settings.setdefault(m.setting, []).append(m)
    header = ["setting"] + pnames + ["n", "failed"]
    for q in scalars:
        header += [f"{q.name}_mean", f"{q.name}_sd", f"{q.name}_ci95_low", f"{q.name}_ci95_high"]
    rows, summary = [], {}
    for si, ms in sorted(settings.items()):
        done = [m for m in ms if m.id in values]
        failed = sum(1 for m in ms if by_id[m.id][1] == records.FAILED)
        row = [si] + [ms[0].values[p] for p in pnames] + [len(done), failed]
        summary[si] = {}
        for q in scalars:
            vals = [values[m.id][q.name] for m in done]
            n, mean, sd, lo, hi = summarise(vals)
            summary[si][q.name] = (n, mean, sd, lo, hi, vals)
            row += [mean, sd, lo, hi]
        rows.append(row)
    write_csv_atomic(out / "summary.csv", header, rows)
    written = [out / "members.csv", out / "summary.csv"]

    series_stats = {}
    for q in series:
        per_setting = {}
        for si, ms in sorted(settings.items()):
            done = [m for m in ms if m.id in values]
            if not done:
                continue
            # The grid of the setting's first member, within the span all its members share;
            # the others are interpolated onto it (identical grids need no interpolation).
            lo = max(values[m.id][q.name][0][0] for m in done)
            hi = min(values[m.id][q.name][0][-1] for m in done)
            grid = [x for x in values[done[0].id][q.name][0] if lo <= x <= hi]
            mean, sd = [], []
            for x in grid:
                ys = [interpolate(*values[m.id][q.name], x) for m in done]
                _, mu, s, _, _ = summarise(ys)
                mean.append(mu)
                sd.append(s)
            per_setting[si] = (grid, mean, sd, len(done))
        series_stats[q.name] = per_setting
        # One file per quantity: time, then mean and sd of each setting, on the union of the
        # settings' grids (a setting without a row at a time has an empty cell).
        times = sorted({x for g, _, _, _ in per_setting.values() for x in g})
        cols = ["time"]
        lookup = []
        for si, (g, mu, s, _) in per_setting.items():
            cols += [f"s{si}_mean", f"s{si}_sd"]
            lookup.append(({x: i for i, x in enumerate(g)}, mu, s))
        rows = []
        for x in times:
            row = [x]
            for pos, mu, s in lookup:
                i = pos.get(x)
                row += [mu[i], s[i]] if i is not None else ["", ""]
            rows.append(row)
        path = out / f"series_{q.name}.csv"
        write_csv_atomic(path, cols, rows)
        written.append(path)

    if plots:
        if importlib.util.find_spec("matplotlib") is None:
            log("demfem sweep: matplotlib is not installed (Debian: python3-matplotlib): no "
                "plots; the tables are written")
        else:
            from sweep import plots as plotting
            written += plotting.draw(spec, plan, settings, summary, series_stats, out / "plots")
    n_done = len(values)
    if n_done < len(plan.members):
        log(f"demfem sweep: {len(plan.members) - n_done} of {len(plan.members)} members are not "
            "done; the tables cover the done ones (members.csv gives each member's status)")
    return written
