#!/usr/bin/python3
"""ctest: the studies package (tools/studies) on top of the sweep.

  test_studies.py units
      the sheet study's settings as sweeps, planned (no run): stability is the 16 members
      of scheme x force averaging x dt_F with the overrides the old text edits made;
      convergence the base and its variants (dt_D halved, 5 mm shells, two threads, gravity
      1e-9 larger), each changing its one key only
  test_studies.py sheet BUILD/bin/demfem_run
      `tools/sheet_study.py convergence --members threads_2 --end-time 0.05` as documented
      (docs/verification.md), short: both members done, the fill made once in the study's
      shared bed folder, and the member on two DEM threads equal to the base bit for bit
      (the CPU backend's determinism: every physics column of coupling.csv, and the RMS
      difference of the deflection 0 exactly)
"""

import json
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from sweep_testing import SOURCE, check, read_csv  # first: it puts tools/ on sys.path

BASE = SOURCE / "cases" / "sheet_ci.toml"


def plan_of(text, tmp):
    from sweep.plan import build_plan
    from sweep.sweep_file import read_sweep_file
    path = Path(tmp) / "s.toml"
    path.write_text(text)
    return build_plan(read_sweep_file(path), Path(tmp) / "out", "/bin/true")


def case_units(tmp):
    from studies import sheet
    from studies.sweep_study import sweep_file_text
    stability = [("scheme", {"coupling.scheme": list(sheet.SCHEMES)}),
                 ("force_averaging", {"coupling.force_averaging": list(sheet.AVERAGING)}),
                 ("dt_f", {"fem.dt": list(sheet.DT_F)})]
    plan = plan_of(sweep_file_text("stability", BASE, stability, [], sheet.EXECUTION), tmp)
    check(len(plan.members) == 16 and plan.run_dir == str(Path(tmp, "out", "beds")),
          f"stability: {len(plan.members)} members, run_dir {plan.run_dir}")
    m = plan.members[13]  # predictive, averaging, 2e-4 (the last axis changes fastest)
    check(m.overrides[:3] == ['coupling.scheme="predictive"', "coupling.force_averaging=true",
                              "fem.dt=0.0002"], f"stability member 13: {m.overrides}")
    check(plan.args == ["--no-post"], f"stability: demfem_run args {plan.args}")
    scene = tomllib.loads(BASE.read_text())
    dt, cells = scene["dem"]["dt"], scene["fem"]["mesh"]["plate"]["cells"]
    keys = {"dem.dt": [dt, dt / 2, dt, dt, dt],
            "fem.mesh.plate.cells": [cells, cells, [2 * c for c in cells], cells, cells],
            "dem.threads": [1, 1, 1, 2, 1],
            "dem.gravity": [sheet.GRAVITY] * 4 + [sheet.GRAVITY_PERTURBED]}
    plan = plan_of(sweep_file_text("convergence", BASE, [("dem.dt", keys)], [],
                                   sheet.EXECUTION), tmp)
    base = plan.members[0].overrides
    for i, changed in enumerate([None, "dem.dt", "fem.mesh.plate.cells", "dem.threads",
                                 "dem.gravity"]):
        o = plan.members[i].overrides
        differ = [a.split("=")[0] for a, b in zip(o, base) if a != b]
        check(differ == ([changed] if changed else []),
              f"convergence member {i} changes {differ}, expected {changed}")
    check(plan.members[3].threads == 2, "the two-thread member does not get two cores")


def case_sheet(tmp, exe):
    work = Path(tmp) / "work"
    r = subprocess.run([sys.executable, str(SOURCE / "tools" / "sheet_study.py"), "convergence",
                        "--members", "threads_2", "--end-time", "0.05", "--work", str(work),
                        "--bin", str(Path(exe).parent)], capture_output=True, text=True)
    print(r.stdout, r.stderr, sep="\n")
    check(r.returncode == 0, f"sheet_study.py exited {r.returncode}")
    rows = {x["member"]: x for x in json.loads((work / "convergence.json").read_text())}
    check(set(rows) == {"base", "threads_2"} and
          all(x["status"] == 0 for x in rows.values()), f"convergence.json: {rows}")
    check(rows["threads_2"]["rms_diff"] == 0.0,
          f"two DEM threads differ from one: RMS {rows['threads_2']['rms_diff']}")
    fills = list((work / "convergence" / "beds" / "out").glob("sheet_fill_ci/dem_state.h5"))
    check(len(fills) == 1 and not list((work / "convergence" / "members").glob("*/out")),
          "the fill was not made once in the study's shared bed folder")
    cols = ["time", "kinetic_energy", "max_overlap", "fem_max_displacement", "force_sum_z"]
    a, b = (read_csv(work / "convergence" / "members" / m / "coupling.csv")
            for m in ("s00_r00", "s01_r00"))
    pick = [[row[a[0].index(c)] for c in cols] for row in a[1]]
    check(pick == [[row[b[0].index(c)] for c in cols] for row in b[1]],
          "coupling.csv of two DEM threads differs from one thread")
    check(any(float(x[1]) > 0 for x in pick), "no kinetic energy: the check would be empty")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory(prefix="demfem-studies-test-") as d:
        try:
            case_units(d) if sys.argv[1] == "units" else case_sheet(d, sys.argv[2])
        except Exception as e:  # Failure, or an error of the study
            print(f"FAILED: {e}", file=sys.stderr)
            sys.exit(1)
    print(f"ok: {sys.argv[1]}")
