#!/usr/bin/python3
"""The thesis's parameter studies on the sleeper (ch. 6, figs. 6.7, 6.10, 6.12) on the small
sleeper chain (cases/sleeper_bed1_mini.toml -> sleeper_bed2_mini.toml -> sleeper_mini.toml),
each setting repeated with several seeds, as mean +- sd (docs/cases.md, "Thesis studies").

usage: tools/sleeper_study.py run STUDY [STUDY ...] [--seeds 1,2,3] [--cycles 3] [--jobs 2]
                              [--out out/sleeper_study] [--bin-dir build/bin]
       tools/sleeper_study.py collect STUDY [STUDY ...] [--out ...] [--figures docs/figures]

STUDY is time_scale (1, 2, 10, 20), friction (rock-rock 0.3, 0.6, 0.9) or triangles (10, 30,
40 per rock). Every member is a chain: the two bed preparations with the member's seed (and
its friction or triangles: they change the bed) and the load case on that bed. Members
with the same bed settings and seed share one bed (the time-scale members of a seed; the
friction 0.6 and triangles 10 members are the time-scale study's time scale 10 members, the
baseline). Finished beds and members are skipped when run again.

Why a script and not `demfem sweep`: a sweep member is one `demfem_run` of one scene with
`--set` overrides, and a load case prepares its `[dem.load] scene = ...` chain from the
files as written: the overrides of a member do not reach the bed scenes, and a state made
with overrides would count as current for the plain file (the state records the hash of the
file's text only). Here each bed stage runs in its own folder with its overrides, and the
load case runs in that folder, so it finds the bed it needs there.

A bed of another seed, friction or rock shape has another top: the sleeper is placed 4 mm
above the highest rock under it (the `under_sleeper` sensor's `top` at the end of the second
preparation, as docs/cases.md places it for the committed bed), with a mesh of its own
(cases/geometry/make_sleeper.py --z0), and the load case's z selectors and probes moved
with it (overrides).

Seeds: bed 1 takes run.seed = seed, bed 2 seed + 1000. Where the random insertion does not
fit (the small chain's bands are at their capacity) or a preparation blows up, both stages
run again with the seeds + 100 k (k = 1, 2, ...; at most INSERT_TRIES pairs); bed.json and
bed_rejected.json record the seeds used and rejected.

The load pattern: the thesis's (fig. 6.2, `"sleeper"` amplitude) with `--cycles` cycles
(default 3; the thesis: 6), time scale 10 for the friction and triangles studies (the
thesis's choice), then held at the peak for 0.04 s (the cells' pressures: mean over it).

`run` writes under OUT: beds/<bed>_s<seed>/ (bed.json: the top, z0, CPU seconds) and
<study>/<setting>_s<seed>/ (the load case's output, member.json with its overrides and CPU
seconds, and sleeper_report.py's plots and sleeper_report.json). `collect` writes
<study>/summary.csv and summary.json (mean, sd over the seeds of each setting), prints the
table, and draws <figures>/sleeper_study_<study>.png: the settlement since the load start
against the reference time (t - start) / time scale, mean with a pale +- sd band per setting.
Exit status 2 on bad arguments, 1 when a run fails.
"""

import argparse
import csv
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from demfem_post import load_scene, read_csv
from demfem_post.plots import pyplot_or_exit
from sweep import scene_keys
from sweep.exit_status import EXIT_BAD_INPUT, EXIT_BLOW_UP

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

CASES = os.path.join(ROOT, "cases")
BED1 = os.path.join(CASES, "sleeper_bed1_mini.toml")
BED2 = os.path.join(CASES, "sleeper_bed2_mini.toml")
LOAD = os.path.join(CASES, "sleeper_mini.toml")
MAKE_SLEEPER = os.path.join(CASES, "geometry", "make_sleeper.py")
PYTHON = "/usr/bin/python3"

GAP = 0.004          # m: the sleeper's bottom above the highest rock under it (docs/cases.md)
HEIGHT = 0.18        # m: the sleeper's height (table 6.1)
Y0 = 0.4             # m: its lower y edge in the 0.3 m slice
INSERT_TRIES = 12    # seed pairs tried per bed (insertion that does not fit, blow-up)
INSERT_SEED_STEP = 100
HOLD = 0.04          # s: held at the peak after the pattern
SEAT_KEYS = ("fem.pressures[1].amplitude", "fem.pressures[2].amplitude")
BASE_TIME_SCALE = 10.0  # thesis 6.4.1: the studies ran at time scale 10

# study -> (parameter label, unit, values, bed overrides of a value, load overrides of a value)
STUDIES = {
    "time_scale": ("time scale", "", [1.0, 2.0, 10.0, 20.0],
                   lambda v: {}, lambda v: {"time_scale": v}),
    "friction": ("rock-rock friction", "", [0.3, 0.6, 0.9],
                 lambda v: {"dem.pairs[0].friction": v},
                 lambda v: {"time_scale": BASE_TIME_SCALE, "dem.pairs[0].friction": v}),
    "triangles": ("triangles per rock", "", [10, 30, 40],
                  lambda v: {"dem.shapes[0].triangles": v},
                  lambda v: {"time_scale": BASE_TIME_SCALE}),
}
DEFAULT_BED = {"dem.pairs[0].friction": 0.6, "dem.shapes[0].triangles": 10}  # the scenes'


def fmt(v):
    return f"{v:g}" if isinstance(v, float) else str(v)


def bed_name(bed):
    """Beds equal to the scenes' own settings share the name 'base'."""
    diff = {k: v for k, v in bed.items() if DEFAULT_BED.get(k) != v}
    if not diff:
        return "base"
    return "_".join(k.split(".")[-1].split("[")[0] + fmt(v) for k, v in sorted(diff.items()))


def sets(overrides):
    out = []
    for k, v in overrides.items():
        out += ["--set", f"{k}={scene_keys.toml_value(v)}"]
    return out


STOP = threading.Event()  # Ctrl-C or SIGTERM: no new runs, the running ones stopped
RUNNING = set()
RUNNING_LOCK = threading.Lock()


def stop_all(signum, frame):
    STOP.set()
    with RUNNING_LOCK:
        for p in RUNNING:
            try:
                p.send_signal(signal.SIGINT)  # demfem_run stops its solvers cleanly
            except ProcessLookupError:
                pass


def run_logged(cmd, cwd, log_path):
    """Runs cmd with its output into log_path; returns (exit status, CPU seconds of it and
    its children: the solvers)."""
    with open(log_path, "a") as log:
        log.write("$ " + " ".join(cmd) + "\n")
        log.flush()
        with RUNNING_LOCK:
            if STOP.is_set():
                raise RuntimeError("stopped")
            # its own process group: the terminal's Ctrl-C reaches this script only
            p = subprocess.Popen(["nice", "-n", "10"] + cmd, cwd=cwd, stdout=log,
                                 stderr=subprocess.STDOUT, start_new_session=True)
            RUNNING.add(p)
        _, status, ru = os.wait4(p.pid, 0)
        with RUNNING_LOCK:
            RUNNING.discard(p)
        p.returncode = os.waitstatus_to_exitcode(status)
    return p.returncode, ru.ru_utime + ru.ru_stime


class Runner:
    def __init__(self, out, bin_dir, cycles):
        self.out = os.path.abspath(out)
        self.demfem_run = os.path.join(os.path.abspath(bin_dir), "demfem_run")
        self.cycles = cycles
        self.bed_locks = {}
        self.lock = threading.Lock()

    def log(self, msg):
        with self.lock:
            print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)

    def bed(self, bed, seed):
        """Prepares (once) the bed of these settings and seed; returns its folder and bed.json."""
        folder = os.path.join(self.out, "beds", f"{bed_name(bed)}_s{seed}")
        with self.lock:
            lk = self.bed_locks.setdefault(folder, threading.Lock())
        with lk:
            rec_path = os.path.join(folder, "bed.json")
            want = {"seed": seed, "overrides": bed}
            if os.path.exists(rec_path):
                rec = json.load(open(rec_path))
                if {k: rec[k] for k in want} == want:
                    return folder, rec
                raise RuntimeError(f"{folder}: made with other settings ({rec_path}); remove it")
            os.makedirs(folder, exist_ok=True)
            failed_path = os.path.join(folder, "bed_failed.json")
            if os.path.exists(failed_path):
                raise RuntimeError(f"{folder}: no bed ({failed_path}); remove it to try again")
            cpu, rejected = {"bed1": 0.0, "bed2": 0.0}, []
            rejected_path = os.path.join(folder, "bed_rejected.json")
            if os.path.exists(rejected_path):  # an earlier run's: not tried again
                rejected = json.load(open(rejected_path))
            for attempt in range(INSERT_TRIES):
                if any(r["attempt"] == attempt for r in rejected):
                    continue
                # both stages with the next seeds when one fails: the random insertion of the
                # bands is near their capacity (about 33 rocks in 0.5 m of the slice,
                # docs/cases.md), and some beds blow up while the plate compacts them
                used = {"bed1": seed + INSERT_SEED_STEP * attempt,
                        "bed2": seed + 1000 + INSERT_SEED_STEP * attempt}
                why = None
                for stage, scene in (("bed1", BED1), ("bed2", BED2)):
                    log_path = os.path.join(folder, f"{stage}.log")
                    self.log(f"bed {os.path.basename(folder)}: {stage} (seed {used[stage]})")
                    start = os.path.getsize(log_path) if os.path.exists(log_path) else 0
                    code, c = run_logged([self.demfem_run, scene, "--quiet"] +
                                         sets({"run.seed": used[stage], **bed}), folder, log_path)
                    cpu[stage] += c
                    with open(log_path) as f:
                        f.seek(start)
                        full = code == EXIT_BAD_INPUT and "cannot insert" in f.read()
                    if full or code == EXIT_BLOW_UP:
                        why = "random insertion found no place for every rock" if full else \
                            "preparation blew up"
                        break
                    if code != 0:
                        raise RuntimeError(f"{folder}: {stage} ended with status {code} "
                                           f"(log {log_path})")
                if why is None:
                    break
                self.log(f"bed {os.path.basename(folder)}: {stage} seed {used[stage]}: {why}; "
                         "next seeds")
                rejected.append({"attempt": attempt, "stage": stage, "seeds": dict(used),
                                 "why": why})
                with open(rejected_path, "w") as f:
                    json.dump(rejected, f, indent=1)
            else:
                with open(failed_path, "w") as f:
                    json.dump({**want, "seeds_rejected": rejected}, f, indent=1)
                raise RuntimeError(f"{folder}: no bed in {INSERT_TRIES} tries of seeds")
            # where the load case's sleeper goes: above the highest rock under it
            top_path = os.path.join(folder, "out", "sleeper_bed2_mini", "sensor_under_sleeper.csv")
            top = read_csv(top_path).column("top")[-1]
            z0 = round(top + GAP, 6)
            mesh = os.path.join(folder, "sleeper.inp")
            subprocess.run([PYTHON, MAKE_SLEEPER, "--z0", f"{z0}", "--y0", f"{Y0}", "--out", mesh],
                           check=True, stdout=subprocess.DEVNULL)
            rec = {**want, "seeds_used": used, "seeds_rejected": rejected, "top": top, "z0": z0, "mesh": mesh, "cpu_s": cpu}
            with open(rec_path + ".part", "w") as f:
                json.dump(rec, f, indent=1)
            os.replace(rec_path + ".part", rec_path)
            self.log(f"bed {os.path.basename(folder)}: top {top:.4f} m, sleeper at {z0:.4f} m, "
                     f"CPU {cpu['bed1']:.0f} + {cpu['bed2']:.0f} s")
            return folder, rec

    def load_overrides(self, z0, load):
        """The load case's overrides: the sleeper at z0 (mesh, selectors, probes), the
        pattern (time scale, cycles), the end time and the study's keys."""
        base = load_scene(LOAD)
        ts = load.pop("time_scale")
        o = {"fem.clamps[0].nodes": f"x >= 1.599 and x <= 1.601 and z <= {z0 + 1e-4:.6f}",
             "fem.pressures[0].surface": f"z >= {z0 + HEIGHT - 1e-4:.6f}"}
        for i, p in enumerate(base["fem"]["monitor"]["probes"]):
            o[f"fem.monitor.probes[{i}].point"] = [p["point"][0], p["point"][1], z0]
        start = None
        for key in SEAT_KEYS:
            amp = scene_keys.get(base, key)
            start = amp.get("start_time", 0.0)
            o[key + ".time_scale"] = ts
            o[key + ".cycles"] = self.cycles
        # the pattern's length (time_function.hpp): two ramps, the unloading, the cycles
        pattern = ts * (2 * amp.get("ramp_duration", 0.03) + amp.get("unload_duration", 0.0) +
                        self.cycles / amp.get("cycle_frequency", 100.0))
        end = round(start + pattern + HOLD, 6)
        o["run.end_time"] = end
        o.update(load)
        return o, (round(end - HOLD, 6), end)

    def member(self, study, value, seed):
        folder = os.path.join(self.out, study, f"{fmt(value)}_s{seed}")
        with self.lock:
            lk = self.bed_locks.setdefault(folder, threading.Lock())
        with lk:
            return self._member(study, value, seed)

    def _member(self, study, value, seed):
        label, _, _, bed_of, load_of = STUDIES[study]
        bed = {**DEFAULT_BED, **bed_of(value)}
        folder = os.path.join(self.out, study, f"{fmt(value)}_s{seed}")
        rec_path = os.path.join(folder, "member.json")
        if os.path.exists(rec_path) and json.load(open(rec_path)).get("status") == "done":
            return json.load(open(rec_path))
        bed_folder, bed_rec = self.bed(bed, seed)
        overrides, hold = self.load_overrides(bed_rec["z0"], load_of(value))
        # the mesh is the bed's own (an absolute path: relative ones are the scene's folder's)
        overrides["fem.mesh.file"] = bed_rec["mesh"]
        os.makedirs(folder, exist_ok=True)
        # the baseline (friction 0.6, 10 triangles, time scale 10) is one run for all studies
        shared = None
        if study != "time_scale" and bed_name(bed) == "base":
            shared = os.path.join(self.out, "time_scale", f"{fmt(BASE_TIME_SCALE)}_s{seed}")
        rec = {"study": study, "parameter": label, "value": value, "seed": seed,
               "bed": bed_folder, "z0": bed_rec["z0"], "hold": hold,
               "overrides": [f"{k}={scene_keys.toml_value(v)}" for k, v in overrides.items()]}
        if shared:
            self.member("time_scale", BASE_TIME_SCALE, seed)  # runs it or waits for it
            rec.update(status="done", output=shared, cpu_s=0.0, shared_with=shared)
        else:
            self.log(f"{study} {fmt(value)} seed {seed}: load case to t = {hold[1]} s")
            t0 = time.time()
            prev = {}
            if os.path.exists(os.path.join(folder, "run.json")):
                prev = json.load(open(os.path.join(folder, "run.json")))
            if prev.get("exit_code") == 0 and prev.get("overrides") == rec["overrides"]:
                code, cpu = 0, json.load(open(rec_path)).get("cpu_s", float("nan")) \
                    if os.path.exists(rec_path) else float("nan")  # only the report was missing
            else:
                code, cpu = run_logged([self.demfem_run, LOAD, "--output-dir", folder, "--no-post",
                                    "--quiet"] + sum((["--set", o] for o in rec["overrides"]), []),
                                       bed_folder, os.path.join(folder, "run.log"))
            if code != 0:
                raise RuntimeError(f"{folder}: the load case ended with status {code} "
                                   f"(log {folder}/run.log)")
            rec.update(status="ran", output=folder, cpu_s=cpu, wall_s=time.time() - t0)
            with open(rec_path + ".part", "w") as f:
                json.dump(rec, f, indent=1)
            os.replace(rec_path + ".part", rec_path)  # the report may fail: the run is kept
            rep = subprocess.run([PYTHON, os.path.join(HERE, "sleeper_report.py"), folder,
                                  "--scene", LOAD, "--hold", f"{hold[0]},{hold[1]}"] +
                                 sum((["--set", o] for o in rec["overrides"]), []),
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if rep.returncode != 0:
                raise RuntimeError(f"{folder}: sleeper_report.py: {rep.stderr.strip()}")
            rec["status"] = "done"
            self.log(f"{study} {fmt(value)} seed {seed}: done, CPU {cpu:.0f} s")
        with open(rec_path + ".part", "w") as f:
            json.dump(rec, f, indent=1)
        os.replace(rec_path + ".part", rec_path)
        return rec


def cmd_run(a):
    seeds = [int(s) for s in a.seeds.split(",")]
    r = Runner(a.out, a.bin_dir, a.cycles)
    jobs = [(st, v, s) for st in a.studies for s in seeds for v in STUDIES[st][2]]
    # seed by seed (every study gets its repetitions early); the time-scale study first
    # in each: its time scale 10 member is the others' baseline
    jobs.sort(key=lambda j: (j[2], j[0] != "time_scale", STUDIES[j[0]][2].index(j[1])))
    failed = []
    signal.signal(signal.SIGINT, stop_all)
    signal.signal(signal.SIGTERM, stop_all)
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = {pool.submit(r.member, *j): j for j in jobs}
        for f, j in futures.items():
            try:
                f.result()
            except Exception as e:  # report every failure, run the rest
                failed.append(j)
                r.log(f"FAILED {j}: {e}")
    if STOP.is_set():
        return 130
    return 1 if failed else 0


# ---------------------------------------------------------------- collect

def mean_sd(v):
    v = [x for x in v if x is not None and math.isfinite(x)]
    if not v:
        return float("nan"), float("nan"), 0
    m = sum(v) / len(v)
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else float("nan")
    return m, sd, len(v)


def member_series(rec):
    """(reference time, settlement since the load start in mm) of a member, and its scalars."""
    out = rec["output"]
    sc = load_scene(LOAD, rec["overrides"])
    amp = scene_keys.get(sc, SEAT_KEYS[0])
    ts, start, cycles = amp["time_scale"], amp.get("start_time", 0.0), amp["cycles"]
    ramp, f = amp.get("ramp_duration", 0.03), amp.get("cycle_frequency", 100.0)
    c0 = ramp + amp.get("unload_duration", 0.0)  # the cycles' start (reference time)
    mon_path = os.path.join(out, "fem_monitor.csv")
    mon = read_csv(mon_path)
    t = mon.column("time")
    probes = sorted(h[:-3] for h in mon if h.startswith("b") and h.endswith("_uz"))
    uz = [mon.column(p + "_uz") for p in probes]
    s = [1e3 * sum(u[i] for u in uz) / len(uz) for i in range(len(t))]

    def at(time_):
        return s[min(range(len(t)), key=lambda j: abs(t[j] - time_))]

    s0 = at(start)
    tau = [(x - start) / ts for x in t]
    rel = [x - s0 for x in s]
    mins = [at(start + ts * (c0 + k / f)) - s0 for k in range(cycles + 1)]
    amps = []
    for k in range(cycles):  # the sleeper's up-and-down within each load cycle
        a0, a1 = start + ts * (c0 + k / f), start + ts * (c0 + (k + 1) / f)
        w = [x for x, y in zip(s, t) if a0 <= y <= a1]
        amps.append(max(w) - min(w))
    rep = json.load(open(os.path.join(out, "sleeper_report.json")))
    hold = rep.get("hold", {})
    scal = {"seating_mm": s0, "peak_mm": at(start + ts * ramp) - s0,
            "cycle1_mm": mins[1], "last_cycle_mm": mins[-1], "final_mm": rel[-1],
            "cycle_amplitude_mm": sum(amps) / len(amps),
            "tilt_final_mm": rep.get("tilt_final_mm")}
    for name, p in hold.get("cell_pressure_kPa", {}).items():
        scal[f"{name}_kPa"] = p
    for label, e in hold.get("strain", {}).items():
        scal[f"strain_{label}_hold_ue"] = 1e6 * e
    for label, g in rep.get("strain", {}).items():
        scal[f"strain_{label}_max_ue"] = 1e6 * g["max"]
    if "max_principal_strain" in rep:
        scal["max_principal_strain_ue"] = 1e6 * rep["max_principal_strain"]
    cpu_rec = rec
    if rec.get("shared_with"):  # the baseline's run, made once for the studies
        cpu_rec = json.load(open(os.path.join(rec["shared_with"], "member.json")))
    scal["cpu_s"] = cpu_rec.get("cpu_s")
    return tau, rel, scal, (c0, f, cycles), mins


def cmd_collect(a):
    plt = pyplot_or_exit("sleeper_study.py")
    for study in a.studies:
        label, unit, values, _, _ = STUDIES[study]
        folder = os.path.join(os.path.abspath(a.out), study)
        rows, curves = [], {}
        pattern = None
        for v in values:
            recs = []
            for name in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
                p = os.path.join(folder, name, "member.json")
                if name.startswith(f"{fmt(v)}_s") and os.path.exists(p):
                    r = json.load(open(p))
                    if r.get("status") == "done":
                        recs.append(r)
            if not recs:
                continue
            series = [member_series(r) for r in recs]
            pattern = series[0][3]
            keys = list(series[0][2])
            row = {"setting": fmt(v), "n": len(recs),
                   "seeds": " ".join(str(r["seed"]) for r in recs)}
            for k in keys:
                m, sd, _ = mean_sd([s[2].get(k) for s in series])
                row[k + "_mean"], row[k + "_sd"] = m, sd
            rows.append(row)
            # the members on the first member's reference-time grid (interpolated)
            grid = series[0][0]
            lo = max(0.0, max(s[0][0] for s in series))  # from the load start
            hi = min(s[0][-1] for s in series)
            grid = [x for x in grid if lo <= x <= hi]
            ys = []
            for tau, rel, *_ in series:
                j, y = 0, []
                for x in grid:
                    while j + 1 < len(tau) - 1 and tau[j + 1] < x:
                        j += 1
                    x0, x1 = tau[j], tau[j + 1]
                    w = 0.0 if x1 == x0 else min(1.0, max(0.0, (x - x0) / (x1 - x0)))
                    y.append(rel[j] + w * (rel[j + 1] - rel[j]))
                ys.append(y)
            ms = [mean_sd([y[i] for y in ys]) for i in range(len(grid))]
            curves[fmt(v)] = (grid, [m for m, _, _ in ms], [sd for _, sd, _ in ms], len(recs),
                              [mean_sd([x[4][k] for x in series])[:2]
                               for k in range(len(series[0][4]))])
        if not rows:
            print(f"{study}: no finished members in {folder}", file=sys.stderr)
            return 1
        fields = list(rows[0])
        for path, write in (("summary.csv", None), ("summary.json", None)):
            full = os.path.join(folder, path)
            with open(full + ".part", "w", newline="") as f:
                if path.endswith(".csv"):
                    w = csv.DictWriter(f, fieldnames=fields)
                    w.writeheader()
                    for r in rows:
                        w.writerow({k: (repr(x) if isinstance(x, float) else x)
                                    for k, x in r.items()})
                else:
                    json.dump({"study": study, "parameter": label, "rows": rows}, f, indent=1)
            os.replace(full + ".part", full)
        print(f"\n{study} ({label}): mean +- sd over the seeds; settlement since the load "
              "start (mm, negative down), cell pressures in the hold (kPa), strain (microstrain)")
        show = ["seating_mm", "peak_mm", "cycle1_mm", "last_cycle_mm", "final_mm",
                "cycle_amplitude_mm", "cell1_kPa", "cell2_kPa", "cell3_kPa", "cell4_kPa",
                "cell5_kPa", "strain_centre_hold_ue", "strain_seat1_hold_ue",
                "strain_centre_max_ue", "max_principal_strain_ue", "cpu_s"]
        show = [k for k in show if k + "_mean" in rows[0]]
        print("setting  n  " + "  ".join(f"{k:>18}" for k in show))
        for r in rows:
            print(f"{r['setting']:>7} {r['n']:2d}  " + "  ".join(
                f"{r[k + '_mean']:9.3g} ±{r[k + '_sd']:8.2g}" for k in show))
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5),
                                      gridspec_kw={"width_ratios": [2.2, 1]})
        for name, (g, m, sd, n, at_min) in curves.items():
            line, = ax.plot(g, m, lw=1.2, label=f"{label} {name} (n = {n})")
            ax.fill_between(g, [a - b for a, b in zip(m, sd)], [a + b for a, b in zip(m, sd)],
                            color=line.get_color(), alpha=0.2, lw=0)
            ax2.errorbar(range(len(at_min)), [x[0] for x in at_min],
                         yerr=[0.0 if math.isnan(x[1]) else x[1] for x in at_min], marker="o",
                         capsize=3, color=line.get_color(), label=f"{name}")
        if pattern:
            c0, f, cycles = pattern
            for k in range(cycles + 1):
                ax.axvline(c0 + k / f, color="grey", lw=0.4, ls=":")
        ax.set_xlabel("reference time (t - load start) / time scale (s); dotted: cycle minima")
        ax.set_ylabel("settlement since the load start (mm)")
        ax.set_title(f"sleeper (small chain): {label}, mean ± sd over seeds", fontsize=10)
        ax.legend(fontsize=8)
        ax.grid(True, lw=0.3)
        ax2.set_xticks(range(pattern[2] + 1) if pattern else [])
        ax2.set_xlabel("cycle (0: the first ramp's end, at the peak)")
        ax2.set_ylabel("settlement at the cycle minimum (mm)")
        ax2.set_title("at the cycles' minimum load, mean ± sd", fontsize=10)
        ax2.legend(fontsize=8, title=label, title_fontsize=8)
        ax2.grid(True, lw=0.3)
        fig.tight_layout()
        os.makedirs(a.figures, exist_ok=True)
        png = os.path.join(a.figures, f"sleeper_study_{study}.png")
        fig.savefig(png, dpi=110)
        plt.close(fig)
        print(f"wrote {os.path.join(folder, 'summary.csv')}, {png}")
    return 0


def main(argv):
    ap = argparse.ArgumentParser(description="the thesis's sleeper studies, small scale")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    c = sub.add_parser("collect")
    for p in (r, c):
        p.add_argument("studies", nargs="+", choices=sorted(STUDIES))
        p.add_argument("--out", default=os.path.join("out", "sleeper_study"))
    r.add_argument("--seeds", default="1,2,3")
    r.add_argument("--cycles", type=int, default=3)
    r.add_argument("--jobs", type=int, default=2)
    r.add_argument("--bin-dir", default=os.path.join(ROOT, "build", "bin"))
    c.add_argument("--figures", default=os.path.join(ROOT, "docs", "figures"))
    a = ap.parse_args(argv)
    if a.cmd == "run":
        if a.cycles < 1 or a.jobs < 1:
            ap.error("--cycles and --jobs must be >= 1")
        return cmd_run(a)
    return cmd_collect(a)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
