#!/usr/bin/python3
"""ctest: a chained sweep run locally, cases/sweeps/beam_chain_ci.toml (docs/sweeps.md,
"Chained stages"): each member pours its spheres (stage "pour", DEM only) and then loads the
CI beam with them (stage "load", starting from the pour's end state).

  test_sweep_chain.py CASE BUILD/bin/demfem_run
  chain   every member ran both stages in its folder, the load case from its own pour's
          state; the pour's kinetic energy equals free fall's closed form; the load stage of
          one member equals the same two runs made by hand; heavier loads bend the beam
          more; running the sweep again runs nothing
  resume  a member whose load stage fails on every attempt is reported (stage load) and its
          pour is kept; one whose load stage's demfem_run is killed is retried from that
          stage's checkpoint; run again once the fault is gone, only the failed stage runs,
          and the aggregate equals that of the sweep without faults byte for byte
  shared_beds
          tests/sweep/shared_beds.toml (2 dampings x 2 seeds of a beam whose spheres come
          from a pour that [dem.load] scene prepares per seed): with [execution] beds =
          "shared" the 4 members make 2 pours, in the sweep's bed folder, and their tables
          equal byte for byte those of the same sweep with beds = "member" (4 pours, one in
          each member's folder)
"""

import os
import re
import subprocess
import sys

from sweep_testing import (FAULTS, SOURCE, check, check_nothing_left, env_with, main,
                           read_csv, run_sweep, same_file, status)

CHAIN_FILE = SOURCE / "cases" / "sweeps" / "beam_chain_ci.toml"
# cases/beam_pour_ci.toml: spheres of 24 mm, density 44037.01224873406 kg/m^3, inserted at
# -0.5 m/s and falling for 5 ms under g = 9.81 m/s^2 without touching anything.
DIAMETER, DENSITY, V0, G, T_POUR = 0.024, 44037.01224873406, 0.5, 9.81, 0.005
# Free fall's velocity after n steps of the half-kick/drift/half-kick integrator is exact up
# to rounding (2500 steps of 2e-6 s: ~1e-13 relative); the tolerance is far above that and
# far below any physical difference (one sphere more or less is 1.6 to 3 %).
KE_TOLERANCE = 1e-9


def run_chain(out, exe, *args, **kw):
    return run_sweep(out, *args, demfem_run=exe, sweep_file=CHAIN_FILE, **kw)


def loaded_count(log_text, state):
    m = re.search(r"loaded (\d+) particles from state (\S+);", log_text)
    check(m and m.group(2) == str(state), f"the load stage did not start from {state}")
    return int(m.group(1))


def columns(path, names):
    head, rows = read_csv(path)
    return [[r[head.index(n)] for n in names] for r in rows]


def case_chain(tmp, exe):
    out = tmp / "chain"
    run_chain(out, exe)
    head, rows = read_csv(out / "members.csv")
    check(len(rows) == 4, f"members.csv has {len(rows)} members")
    for r in rows:
        check([r[head.index(c)] for c in ("status", "pour_status", "load_status")] ==
              ["done"] * 3, f"{r[0]}: {r}")
    peak = {}
    for r in rows:
        member = (out / "members" / r[0]).resolve()
        state = member / "pour" / "dem_state.h5"
        log = (member / "load" / "attempt-1.log").read_text()
        check(f'--set dem.load.file="{state}"' in log.splitlines()[0],
              f"{r[0]}: the load stage was not given its own pour's state")
        n = loaded_count(log, state)
        mass = DENSITY * 3.141592653589793 / 6 * DIAMETER ** 3
        want = 0.5 * n * mass * (V0 + G * T_POUR) ** 2
        got = float(r[head.index("pour_kinetic_energy")])
        check(abs(got - want) <= KE_TOLERANCE * want,
              f"{r[0]}: pour kinetic energy {got} J, free fall gives {want} J for {n} spheres")
        peak[(r[head.index("mass")], r[head.index("seed")])] = float(r[head.index("peak_deflection")])
    for seed in ("1", "2"):
        check(peak[("20.0", seed)] > peak[("10.0", seed)],
              f"seed {seed}: 20 kg bent the beam less than 10 kg: {peak}")
    # The chain by hand: the same two runs for member s01_r01 (20 kg, seed 2).
    hand = tmp / "by_hand"
    env = env_with({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"})
    for scene, args in (("beam_pour_ci.toml", ["--set", "dem.insert[0].mass=20.0",
                                              "--set", "run.seed=2"]),
                        ("beam_chain_ci.toml", ["--set", f'dem.load.file="{hand}/pour/dem_state.h5"',
                                               "--set", "dem.load.history=false"])):
        stage = "pour" if "pour" in scene else "load"
        r = subprocess.run([exe, str(SOURCE / "cases" / scene), "--output-dir",
                            str(hand / stage), "--quiet", *args], env=env,
                           capture_output=True, text=True)
        check(r.returncode == 0, f"{scene} by hand: exit {r.returncode}: {r.stderr}")
    physics = ["step", "time", "kinetic_energy", "fem_max_displacement", "force_sum_z"]
    check(columns(hand / "load" / "coupling.csv", physics) ==
          columns(out / "members" / "s01_r01" / "load" / "coupling.csv", physics),
          "member s01_r01's load stage differs from the same two runs made by hand")
    logs = sorted(out.rglob("attempt-*.log"))
    r = run_chain(out, exe)
    check("0 done before" not in r.stdout and "4 done before, 0 to run" in r.stdout,
          "the second sweep did not skip every member")
    check(sorted(out.rglob("attempt-*.log")) == logs, "the second sweep ran a stage again")
    check_nothing_left(out)


def case_resume(tmp, exe):
    ref = tmp / "reference"
    run_chain(ref, exe, "--no-plots")
    out = tmp / "faulty"
    flag = tmp / "fail.flag"
    flag.write_text("")
    env = {"DEMFEM_TEST_REAL_RUN": exe, "DEMFEM_TEST_FAIL": "s00_r01/load",
           "DEMFEM_TEST_FAIL_WHILE": str(flag), "DEMFEM_TEST_KILL": "s01_r00/load=demfem_run"}
    r = run_chain(out, FAULTS, "--no-plots", env=env, expect=1)
    check("s00_r01: failed at stage load (pour done, load failed), 4 attempt(s)" in r.stderr,
          "the member whose load stage fails is not reported with its stage")
    st = status(out, "s00_r01")
    check(st["reason"].startswith("stage load: failed 3 times in a row: exit 1"), st["reason"])
    pour_state = out / "members" / "s00_r01" / "pour" / "dem_state.h5"
    made = pour_state.stat().st_mtime_ns
    marker = (out / "members" / "s01_r00" / "load" / ".test_killed").read_text().strip()
    check(marker != "missed", "s01_r00's load stage ended before the test could kill it")
    a = [x for x in status(out, "s01_r00")["attempts"] if x["stage"] == "load"]
    check(len(a) == 2 and a[0]["exit"] == 137 and a[1]["resume"] and a[1]["exit"] == 0,
          f"s01_r00's load stage (demfem_run killed): attempts {a}")
    flag.unlink()
    r = run_chain(out, FAULTS, "--no-plots", env=env)
    check("3 done before, 1 to run" in r.stdout, "the second sweep did not run just s00_r01")
    check(pour_state.stat().st_mtime_ns == made and
          not (pour_state.parent / "attempt-2.log").exists(),
          "s00_r01's pour stage ran again although it was done")
    for name in ("summary.csv", "series_deflection.csv"):
        same_file(ref / name, out / name, name)
    check_nothing_left(out)


def case_shared_beds(tmp, exe):
    shared_file = SOURCE / "tests" / "sweep" / "shared_beds.toml"
    shared = tmp / "shared"
    run_sweep(shared, "--no-plots", demfem_run=exe, sweep_file=shared_file)
    pours = sorted((shared / "beds").glob("out/beam_pour_ci/set-*/dem_state.h5"))
    check(len(pours) == 2, f"beds = \"shared\": {len(pours)} pours for 2 seeds: {pours}")
    check(not list((shared / "members").glob("*/out")), "a member prepared a pour of its own")
    own_file = tmp / "own_beds.toml"
    own_file.write_text(shared_file.read_text().replace(
        'scene = "beam_pour_load.toml"', f'scene = "{shared_file.parent}/beam_pour_load.toml"')
        .replace('beds = "shared"', 'beds = "member"'))
    own = tmp / "own"
    run_sweep(own, "--no-plots", demfem_run=exe, sweep_file=own_file)
    pours = sorted(own.glob("members/*/out/beam_pour_ci/set-*/dem_state.h5"))
    check(len(pours) == 4 and not (own / "beds").exists(),
          f"beds = \"member\": {len(pours)} pours for 4 members")
    for name in ("summary.csv", "series_deflection.csv"):
        same_file(shared / name, own / name, f"{name} (shared beds, each member's own)")


if __name__ == "__main__":
    os.environ["PYTHONPATH"] = str(SOURCE / "tools")
    sys.exit(main({"chain": case_chain, "resume": case_resume,
                   "shared_beds": case_shared_beds}, sys.argv))
