#!/usr/bin/python3
"""ctest: the sleeper studies (tools/studies/sleeper.py) as sweeps.

  test_sleeper_study.py units
      the dt and time-scale studies planned (no run): the seeds the first axis, each member's
      overrides giving the first layer run.seed S and the second S + 1000 through the load
      case's [dem.load] keys, the member's own seed S (not the scene's), the steps and the
      pattern's end times those of the thesis's pattern computed here by hand
  test_sleeper_study.py seeds BUILD/bin/demfem_run
      the study's seed overrides on a chain of three small DEM scenes (two layers of spheres
      inserted at random, then a run on them) as a sweep of two seeds with shared beds: each
      prepared layer's run.json records the seed it was promised (first S, second S + 1000),
      the first layer equals that scene run by hand with seed S and differs from it with
      S + 1000 (the old sleeper_study.py passed S + 1000 on to the first layer), and each
      layer is made once per seed. A few seconds.
"""

import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from sweep_testing import SOURCE, check  # first: it puts tools/ on sys.path

# Three small DEM scenes: a layer of spheres, a second layer on it, a run on both; each
# passes the run's seed on to the one it loads, as the sleeper chain's scenes do.
# The run, one material and its pair: the start of each of the three scenes.
HEAD = """
[run]
name = "{name}"
end_time = 0.002
seed = 7

[dem]
dt = 1e-5
gravity = [0.0, 0.0, -9.81]
threads = 1

[[dem.materials]]
name = "grain"
youngs_modulus = 1e7
poisson_ratio = 0.3
density = 2600.0

[[dem.pairs]]
a = "grain"
b = "grain"
friction = 0.5
restitution = 0.2
"""
LAYER = HEAD + """{load}
[[dem.insert]]
material = "grain"
lo = [0.0, 0.0, {z0}]
hi = [0.5, 0.5, {z1}]
count = 6
distribution = {{ kind = "constant", diameter = 0.05 }}

[dem.output]
particles = false
state = true
"""
LOAD_OF = """
[dem.load]
scene = "{scene}"
history = false
pass = ["run.seed", "dem.pairs"]
"""
LOAD = HEAD.format(name="on_layers") + """
[dem.load]
scene = "layer2.toml"
pass = ["run.seed", "dem.pairs"]
"""


def last_seed(overrides):
    """The run.seed a run ran with: the last run.seed override (they apply in order)."""
    seeds = [int(o.split("=", 1)[1]) for o in overrides if re.match(r"run\.seed=", o)]
    return seeds[-1] if seeds else None


def case_units(tmp):
    from studies import sleeper
    from studies.sweep_study import sweep_file_text
    from sweep.plan import build_plan
    from sweep.sweep_file import read_sweep_file

    def plan(study, seeds):
        params, holds = sleeper.study_parameters(study, seeds, 3)
        path = Path(tmp) / f"{study}.toml"
        path.write_text(sweep_file_text(study, sleeper.LOAD, params, [], sleeper.EXECUTION))
        return build_plan(read_sweep_file(path), Path(tmp) / study, "/bin/true"), holds

    p, holds = plan("dt", [4, 9])
    steps = [1e-6, 2e-6, 5e-6, 1e-5, 2e-5]
    check(len(p.members) == 10, f"dt: {len(p.members)} members, expected 2 seeds x 5 steps")
    check(p.run_dir == str(Path(tmp, "dt", "beds")), f"dt: members run in {p.run_dir}")
    for m in p.members:
        seed, dt = [4, 9][m.index // 5], steps[m.index % 5]
        o = m.overrides
        check(m.seed == seed and last_seed(o) == seed,
              f"member {m.id}: seed {m.seed}, run.seed {last_seed(o)}, expected {seed}")
        check(f"dem.dt={dt!r}" in o, f"member {m.id}: no dem.dt={dt!r} in {o}")
        load_set = [x for x in o if x.startswith("dem.load.set=")]
        check(len(load_set) == 1, f"member {m.id}: dem.load.set {load_set}")
        bed2 = json.loads(load_set[0].split("=", 1)[1])
        check(bed2[0] == f"run.seed={seed + 1000}" and bed2[-1] ==
              f'dem.load.set=["run.seed={seed}"]' and
              not any("run.seed" in x for x in bed2[1:-1]),
              f"member {m.id}: the second layer's overrides {bed2}")
        check('dem.load.pass=["dem.pairs[0].friction", "dem.shapes"]' in o,
              f"member {m.id}: the load case still passes its seed on: {o}")
    check(all(h == (0.3, 0.45) for h in holds), f"dt: hold windows {holds}, the scene's")
    p, holds = plan("time_scale", [1])
    # the pattern (fig. 6.2): start 0.1 s, two ramps of 0.03 s and 3 cycles at 100 Hz, each
    # stretched by the time scale, then 0.04 s held
    for m, ts in zip(p.members, [1.0, 2.0, 10.0, 20.0]):
        end = 0.1 + ts * (2 * 0.03 + 3 / 100.0) + 0.04
        got = float(next(x for x in m.overrides if x.startswith("run.end_time=")).split("=")[1])
        check(abs(got - end) < 1e-9 and holds[m.setting] == (round(end - 0.04, 6), got),
              f"time scale {ts}: end {got}, hold {holds[m.setting]}, expected end {end}")


def prepared(beds, scene):
    """{seed: folder} of the prepared states of `scene` under the shared bed folder."""
    out = {}
    for run_json in sorted((beds / "out" / scene).glob("set-*/run.json")):
        rec = json.loads(run_json.read_text())
        check(rec["status"] == "completed", f"{run_json}: {rec['status']}")
        seed = last_seed(rec["overrides"])
        check(seed not in out, f"{scene}: two beds with seed {seed}")
        out[seed] = run_json.parent
    return out


def case_seeds(tmp, exe):
    from studies import sleeper
    from studies.sweep_study import members_of, run_study_sweep, sweep_file_text
    import tomllib

    chain = Path(tmp) / "chain"
    chain.mkdir()
    (chain / "layer1.toml").write_text(LAYER.format(name="layer1", load="", z0=0.05, z1=0.5))
    (chain / "layer2.toml").write_text(LAYER.format(
        name="layer2", load=LOAD_OF.format(scene="layer1.toml"), z0=0.5, z1=1.0))
    (chain / "on_layers.toml").write_text(LOAD)
    load = tomllib.loads((chain / "on_layers.toml").read_text())
    layer2 = tomllib.loads((chain / "layer2.toml").read_text())
    seeds = [3, 4]
    rows = [sleeper.seed_overrides(s, load, layer2) for s in seeds]
    keys = {k: [r[k] for r in rows] for k in rows[0]}
    text = sweep_file_text("seeds", chain / "on_layers.toml", [("seed", keys)], [],
                           {"beds": "shared"})
    code = run_study_sweep(tmp, "seeds", text, exe, ["--progress-interval", "0"])
    check(code == 0, f"the sweep exited {code}")
    members = members_of(tmp, "seeds")
    check([st for _, st, _ in members] == ["done", "done"], f"states {members}")
    for m, _, _ in members:
        rec = json.loads((Path(m.folder) / "run.json").read_text())
        check(last_seed(rec["overrides"]) == m.values["seed"],
              f"{m.id}: the load case ran with run.seed {last_seed(rec['overrides'])}, "
              f"its seed is {m.values['seed']}")
    beds = Path(tmp) / "seeds" / "beds"
    first, second = prepared(beds, "layer1"), prepared(beds, "layer2")
    check(sorted(first) == seeds, f"first layers made with seeds {sorted(first)}, "
          f"expected {seeds} (the member's seed)")
    check(sorted(second) == [s + 1000 for s in seeds],
          f"second layers made with seeds {sorted(second)}, expected the seeds + 1000")
    compare = Path(exe).parent / "demfem_h5_compare"
    for s in seeds:
        for by_hand, same in ((s, True), (s + 1000, False)):
            ref = Path(tmp) / f"layer1_by_hand_{by_hand}"
            r = subprocess.run([exe, str(chain / "layer1.toml"), "--output-dir", str(ref),
                                "--set", f"run.seed={by_hand}", "--quiet"],
                               capture_output=True, text=True)
            check(r.returncode == 0, f"layer1 by hand: exit {r.returncode} {r.stderr}")
            # the state's scene hash covers the overrides, which differ (run.output_dir)
            c = subprocess.run([str(compare), str(first[s] / "dem_state.h5"),
                                str(ref / "dem_state.h5"), "--skip", "scene_hash"],
                               capture_output=True, text=True)
            print(f"first layer of seed {s} against layer1 by hand with seed {by_hand}: "
                  f"exit {c.returncode} {c.stdout.strip()[:300]}")
            check((c.returncode == 0) == same,
                  f"the first layer of seed {s} {'differs from' if same else 'equals'} "
                  f"layer1 run by hand with seed {by_hand}")


def main(argv):
    with tempfile.TemporaryDirectory() as tmp:
        if argv[0] == "units":
            case_units(tmp)
        elif argv[0] == "seeds":
            case_seeds(tmp, argv[1])
        else:
            print(f"unknown case {argv[0]}", file=sys.stderr)
            return 2
    print("OK")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except Exception as e:  # a failed check or an error: the message, exit 1
        print(f"FAILED: {e}", file=sys.stderr)
        sys.exit(1)
