"""The sleeper studies (thesis ch. 6, figs. 6.7, 6.10, 6.12, and the DEM time step) on the
small sleeper chain (cases/sleeper_bed1_mini.toml -> sleeper_bed2_mini.toml ->
sleeper_mini.toml), each setting repeated with several seeds, as sweeps (docs/sweeps.md) of
the load case whose beds are prepared once per variant and shared (docs/cases.md, "Thesis
studies" and "Choosing the DEM time step (sleeper)").

usage: python3 -m studies sleeper run STUDY [STUDY ...] [--seeds 1,2,3] [--cycles 3]
                                      [--jobs 2] [--out out/sleeper_study] [--bin-dir build/bin]
       python3 -m studies sleeper collect STUDY [STUDY ...] [--out ...] [--figures docs/figures]
(tools/sleeper_study.py run|collect ... is the same command.)

STUDY is time_scale (1, 2, 10, 20), friction (rock-rock 0.3, 0.6, 0.9), triangles (10, 30,
40 per rock), dt (the DEM step 1e-6, 2e-6, 5e-6, 1e-5 and 2e-5 s) or freeze (the scene's
[dem.freeze] off and on: the rocks below 0.2 m and beyond the sleeper's ends held from the
seating's end). Each study is one sweep in OUT/<study>/ whose members are the seeds x the
settings: `demfem_run cases/sleeper_mini.toml --set ...`, run by the sweep's pool in the
shared bed folder OUT/beds (every study's sweep finds it through OUT/<study>/beds), where the
load case's [dem.load] chain prepares each bed variant (seed, and the friction or triangles
that change the bed) once, under its own lock: the members of a seed with other load
settings (time scale, dt, freeze) load the same bed. Done members are not run again; more
seeds later add members.

Seeds: of seed S, the first layer (sleeper_bed1_mini) is made with run.seed = S, the second
(sleeper_bed2_mini) with S + 1000, so that the layers' insertions draw other positions and
rocks (both scenes seed insertion k with run.seed + k: with one seed the second layer's
bands would repeat the first's rocks and places). The load case's overrides say so through
its [dem.load] keys: it passes only the bed keys of its `pass` list (not run.seed), and sets
the second layer's run.seed, which in turn passes only the bed keys and sets the first
layer's (each prepared bed's run.json lists the overrides it ran with). A seed whose
insertion does not fit (the small chain's bands are near their capacity) is refused by the
sweep's check before anything runs, naming the band: choose other seeds.

The load pattern of the thesis studies: fig. 6.2 (the scene's `"sleeper"` amplitude) with
`--cycles` cycles (default 3; the thesis: 6), time scale 10 for the friction and triangles
studies (the thesis's choice), then held at the peak for 0.04 s (the cells' pressures: the
mean over it). The dt and freeze studies keep the scene's pattern, end time and hold
window (its `[[post]]` sleeper_report.py --hold). The sleeper is seated on each bed by the scene's
[fem.mesh.seat].

`run` writes the sweep file OUT/<study>.sweep.toml, runs it into OUT/<study>/ (members in
members/sSS_rRR/, as `demfem sweep`), then tools/sleeper_report.py into each done member's
folder with the member's hold window. `collect` writes OUT/<study>/study_summary.csv and
study_summary.json (mean, sd over the seeds of each setting; the dt and freeze studies also
each setting's difference from the smallest setting (the smallest step, no freezing), of the
means and per seed on the same bed, beside the seeds' sd there), prints the tables and draws
<figures>/sleeper_study_<study>.png.
Exit status 2 on bad arguments, 1 when a member fails.
"""

import argparse
import os
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

from sweep import scene_keys
from studies.sweep_study import DONE, members_of, run_study_sweep, sweep_file_text

ROOT = Path(__file__).resolve().parents[2]
CASES = ROOT / "cases"
LOAD = CASES / "sleeper_mini.toml"
BED2 = CASES / "sleeper_bed2_mini.toml"
REPORT = ROOT / "tools" / "sleeper_report.py"
PYTHON = "/usr/bin/python3"

BED2_SEED_OFFSET = 1000  # the second layer's run.seed: the member's seed + this
HOLD = 0.04              # s: held at the peak after the thesis studies' pattern
SEAT_KEYS = ("fem.pressures[1].amplitude", "fem.pressures[2].amplitude")
BASE_TIME_SCALE = 10.0   # thesis 6.4.1: the studies ran at time scale 10
# The [[post]] steps are the study's (the hold window of each member); the beds shared.
EXECUTION = {"beds": "shared", "args": ["--no-post"]}


@dataclass
class Study:
    label: str       # the parameter, for tables and plots
    values: list
    keys: object     # value -> {scene key: value} of the load case (None: the scene's)
    pattern: bool    # True: the thesis's pattern with --cycles at the member's time scale


STUDIES = {
    "time_scale": Study("time scale", [1.0, 2.0, 10.0, 20.0], lambda v: {}, True),
    "friction": Study("rock-rock friction", [0.3, 0.6, 0.9],
                      lambda v: {"dem.pairs[0].friction": v}, True),
    "triangles": Study("triangles per rock", [10, 30, 40],
                       lambda v: {"dem.shapes[0].triangles": v}, True),
    "dt": Study("DEM time step (s)", [1e-6, 2e-6, 5e-6, 1e-5, 2e-5],
                lambda v: {"dem.dt": v}, False),
    "freeze": Study("lowest rocks frozen", [False, True],
                    lambda v: {"dem.freeze.enabled": v}, False),
}


def read_scene(path):
    with open(path, "rb") as f:
        return tomllib.load(f)


def _without_seed(passes):
    return [p for p in passes if not scene_keys.under("run.seed", p)]


def seed_overrides(seed, load=None, bed2=None):
    """The load case's overrides that make its beds with seed S: the first layer run.seed S,
    the second S + BED2_SEED_OFFSET (module docstring). Each [dem.load] keeps its `pass` but
    for run.seed, and gets a `set` (after its own entries) naming the next scene's seed."""
    load = load or read_scene(LOAD)
    bed2 = bed2 or read_scene(BED2)
    load_in, bed2_in = load["dem"]["load"], bed2["dem"]["load"]
    bed2_pass = _without_seed(bed2_in.get("pass", []))
    bed2_set = bed2_in.get("set", []) + [f"run.seed={seed}"]
    load_set = load_in.get("set", []) + [
        f"run.seed={seed + BED2_SEED_OFFSET}",
        f"dem.load.pass={scene_keys.toml_value(bed2_pass)}",
        f"dem.load.set={scene_keys.toml_value(bed2_set)}"]
    return {"run.seed": seed, "dem.load.pass": _without_seed(load_in.get("pass", [])),
            "dem.load.set": load_set}


def _pattern_length(amp, cycles):
    """The length (s) of the `"sleeper"` pattern (coupler time_function.hpp): two ramps,
    the unloading, the cycles, at the amplitude's time scale."""
    return amp.get("time_scale", 1.0) * (
        2 * amp.get("ramp_duration", 0.03) + amp.get("unload_duration", 0.0) +
        cycles / amp.get("cycle_frequency", 100.0))


def pattern_overrides(load, time_scale, cycles):
    """The seat loads at this time scale with `cycles` cycles, the run to the end of the
    pattern and HOLD s beyond; returns (overrides, hold window)."""
    o = {}
    for key in SEAT_KEYS:
        o[key + ".time_scale"] = time_scale
        o[key + ".cycles"] = cycles
    amp = dict(scene_keys.get(load, SEAT_KEYS[0]), time_scale=time_scale)
    end = round(amp.get("start_time", 0.0) + _pattern_length(amp, cycles) + HOLD, 6)
    o["run.end_time"] = end
    return o, (round(end - HOLD, 6), end)


def scene_hold(load):
    """The hold window of the scene's own [[post]] sleeper_report.py (its --hold T0,T1)."""
    for post in load.get("post", []):
        args = post.get("args", [])
        if post.get("tool") == REPORT.name and "--hold" in args:
            h0, h1 = (float(x) for x in args[args.index("--hold") + 1].split(","))
            return h0, h1
    raise SystemExit(f"{LOAD}: no [[post]] {REPORT.name} with --hold: the hold window of "
                     "the dt and freeze studies is the scene's")


def setting_overrides(study, value, load, cycles):
    """(the load case's overrides of one setting, its hold window)."""
    st = STUDIES[study]
    keys = dict(st.keys(value))
    if not st.pattern:
        return keys, scene_hold(load)
    ts = value if study == "time_scale" else BASE_TIME_SCALE
    pat, hold = pattern_overrides(load, ts, cycles)
    return {**keys, **pat}, hold


def study_parameters(study, seeds, cycles, load=None):
    """The sweep's two axes: the seeds (run.seed and the [dem.load] overrides that seed each
    layer) and the study's settings (every key zipped); and each setting's hold window."""
    load = load or read_scene(LOAD)
    st = STUDIES[study]
    settings = [setting_overrides(study, v, load, cycles) for v in st.values]
    keys = {k: [o[k] for o, _ in settings] for k in settings[0][0]}
    seed_rows = [seed_overrides(s, load) for s in seeds]
    seed_keys = {k: [r[k] for r in seed_rows] for k in seed_rows[0]}
    # the seeds first: more seeds later add members at the end (the members' numbers stay)
    return [("seed", seed_keys), (study, keys)], [h for _, h in settings]


def _beds_folder(out, study):
    """OUT/<study>/beds, the sweep's shared bed folder, is OUT/beds for every study (a link):
    the studies' members of one seed and bed settings load one bed."""
    shared = Path(out) / "beds"
    shared.mkdir(parents=True, exist_ok=True)
    link = Path(out) / study / "beds"
    link.parent.mkdir(parents=True, exist_ok=True)
    if not link.is_symlink() and not link.exists():
        link.symlink_to(os.path.relpath(shared, link.parent))
    elif not link.is_symlink() and link.resolve() != shared.resolve():
        raise SystemExit(f"{link}: a folder of its own, not the shared {shared}; remove it")


def report_member(member, hold):
    """tools/sleeper_report.py into a done member's folder with its hold window; returns the
    error text or ''."""
    rep = subprocess.run([PYTHON, str(REPORT), member.folder, "--scene", str(LOAD), "--hold",
                          f"{hold[0]},{hold[1]}"] +
                         sum((["--set", o] for o in member.overrides), []),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    return "" if rep.returncode == 0 else rep.stderr.strip()


def run_study(study, a):
    parameters, holds = study_parameters(study, a.seeds, a.cycles)
    _beds_folder(a.out, study)
    text = sweep_file_text(study, LOAD, parameters, [], EXECUTION)
    code = run_study_sweep(a.out, study, text, a.demfem_run, ["--jobs", str(a.jobs)])
    if code >= 2:  # refused before anything ran (a seed's insertion that does not fit), or
        return code  # stopped by a signal: the sweep said why
    failed = code != 0
    for member, state, _ in members_of(a.out, study):
        if state != DONE:
            failed = True
            continue
        if os.path.exists(os.path.join(member.folder, "sleeper_report.json")):
            continue
        err = report_member(member, holds[member.setting % len(holds)])
        if err:
            print(f"{member.folder}: sleeper_report.py: {err}", file=sys.stderr)
            failed = True
    return code if code > 1 else int(failed)


def main(argv):
    ap = argparse.ArgumentParser(prog="python3 -m studies sleeper",
                                 description="the thesis's sleeper studies, small scale")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    c = sub.add_parser("collect")
    for p in (r, c):
        p.add_argument("studies", nargs="+", choices=sorted(STUDIES))
        p.add_argument("--out", default=os.path.join("out", "sleeper_study"))
    r.add_argument("--seeds", default="1,2,3")
    r.add_argument("--cycles", type=int, default=3)
    r.add_argument("--jobs", type=int, default=2)
    r.add_argument("--bin-dir", default=str(ROOT / "build" / "bin"))
    c.add_argument("--figures", default=str(ROOT / "docs" / "figures"))
    a = ap.parse_args(argv)
    a.out = os.path.abspath(a.out)
    if a.cmd == "collect":
        from studies import sleeper_table
        return sleeper_table.collect(a)
    if a.cycles < 1 or a.jobs < 1:
        ap.error("--cycles and --jobs must be >= 1")
    try:
        a.seeds = [int(s) for s in a.seeds.split(",")]
    except ValueError:
        ap.error(f"--seeds {a.seeds}: not a comma-separated list of integers")
    if len(set(a.seeds)) != len(a.seeds) or min(a.seeds) < 0:
        ap.error(f"--seeds {a.seeds}: distinct integers >= 0")
    a.demfem_run = os.path.join(os.path.abspath(a.bin_dir), "demfem_run")
    worst = 0
    for study in a.studies:
        worst = max(worst, run_study(study, a))
    return worst
