"""ctest checks of the DEM side of the SDK (issue 36): demfem_run starts the Python DEM
examples/python_dem_spheres/spheres.py (dem.backend = "external") beside fem_server's beam.

  coupled     the five spheres come to rest on the beam: the interface carries their weight,
              5 x 2 kg x 9.81 m/s^2 = 98.1 N, within 0.1 % (an independent reference: the
              weight, not a number of an earlier run); run.json records the DEM backend and
              its command; --check validates dem.command
  restart     the Python DEM killed in step 115 (the spheres on the beam) is restarted from the last checkpoint like
              dem_server, and the run equals the uninterrupted one (coupling.csv, bitwise);
              its checkpoint is refused by dem_server (--resume --dem-backend cpu, exit 2)
  badinput    a missing dem.command, a program that does not exist (exit 2, naming the key),
              --in-process (exit 2), --dem-backend external on a scene without dem.command
  faults      a program that serves the FEM side (exit 1, refused before it attaches), one that
              raises in step (exit 1), one that writes a NaN force (exit 3, the DEM's blow-up,
              naming the backend and the node, before the FEM is given it) and one that dies
              in every step 5 (restarted, then exit 4): each names the external DEM backend;
              one that hangs in a step is killed after checkpoint.reply_timeout and restarted,
              and its run equals the uninterrupted one

Usage: test_python_dem.py CASE DEMFEM_RUN SOURCE_DIR. Nothing may be left in /dev/shm.
"""

import json
import os
import re
import sys

import coupled_checks as checks  # beside this file
from coupled_checks import check, rows


def run(demfem_run, scene, out, *extra):
    return checks.run(demfem_run, scene, out, *extra, env=checks.ENV,
                              timeout=400)


def scene_of(source):
    return os.path.join(source, "examples/python_dem_spheres/beam_spheres_ci.toml")


def case_coupled(demfem_run, source, d):
    r = run(demfem_run, scene_of(source), d)
    if not check(r.returncode == 0, f"coupled run failed ({r.returncode}): {r.stderr[-2000:]}"):
        return
    check("started the external DEM backend '{python} spheres.py'" in r.stdout,
          "the launcher does not name the external DEM backend")
    last = rows(d)[-1]
    f, ke, u = (float(last[k]) for k in ("force_sum_z", "kinetic_energy", "fem_max_displacement"))
    weight = 5 * 2.0 * 9.81
    print(f"coupled: F_z = {f!r} N (weight {weight} N, {abs(f + weight) / weight:.2e} off), "
          f"kinetic energy {ke:.3e} J, beam max |u| {u:.4e} m")
    check(abs(f + weight) <= 1e-3 * weight, f"the settled force {f} N is not -{weight} N (0.1 %)")
    check(u > 0.0, "the beam did not move under the spheres")
    record = json.load(open(os.path.join(d, "run.json")))
    check(record.get("dem_backend") == "external", f"run.json dem_backend {record.get('dem_backend')}")
    check(record.get("dem_command") == ["{python}", "spheres.py"],
          f"run.json dem_command {record.get('dem_command')}")
    check(record.get("dem_threads") is None, "run.json gives an external DEM dem_threads")
    c = run(demfem_run, scene_of(source), None, "--check")
    check(c.returncode == 0, f"--check of the valid scene: exit {c.returncode}: {c.stderr[-500:]}")
    c = run(demfem_run, scene_of(source), None, "--check", "--set", 'dem.command=["./nothere.py"]')
    check(c.returncode == 2 and "dem.command" in c.stderr and "nothere.py" in c.stderr,
          f"--check of a missing DEM program: exit {c.returncode}: {c.stderr[-500:]}")


def case_restart(demfem_run, source, d):
    a, b = os.path.join(d, "straight"), os.path.join(d, "killed")
    short = ["--set", "run.end_time=0.015"]  # the spheres land at about 10 ms
    ra = run(demfem_run, scene_of(source), a, *short)
    rb = run(demfem_run, scene_of(source), b, *short, "--debug-kill", "dem:115")
    if not (check(ra.returncode == 0, f"uninterrupted run failed: {ra.stderr[-2000:]}") and
            check(rb.returncode == 0, f"killed run failed: {rb.stderr[-2000:]}")):
        return
    check("restarting it" in rb.stderr and "recovered" in rb.stderr,
          f"no restart reported: {rb.stderr[-1500:]}")
    check(rb.stdout.count("started the external DEM backend") == 1 and
          "started external DEM backend '{python} spheres.py'" in rb.stdout,
          f"the restart did not start the DEM backend: {rb.stdout[-800:]}")
    keys = ["step", "time", "drift", "work_dem", "work_fem", "max_overlap", "kinetic_energy",
            "fem_max_displacement", "force_sum_z", "energy_error"]
    xa, xb = rows(a), rows(b)
    check(len(xa) == len(xb) == 150, f"rows {len(xa)} and {len(xb)}, expected 150")
    check(len(xa) > 115 and float(xa[115]["force_sum_z"]) < -100.0,
          "the spheres were not on the beam when it was killed")
    same = all(ra_[k] == rb_[k] for ra_, rb_ in zip(xa, xb) for k in keys)
    check(same, "the restarted run differs from the uninterrupted one")
    print(f"restart: 150 steps, killed in step 115 (spheres on the beam), final force {xb[-1]['force_sum_z']} N in both")
    # A checkpoint of dem_server (examples/python_spring_plate) is refused by an external DEM,
    # before any process starts.
    plate = os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml")
    c = os.path.join(d, "plate")
    r = run(demfem_run, plate, c, "--set", "run.end_time=0.001")
    if not check(r.returncode == 0, f"the dem_server run failed: {r.stderr[-800:]}"):
        return
    spheres = os.path.join(source, "examples/python_dem_spheres/spheres.py")
    r = run(demfem_run, plate, os.path.join(d, "swap"), "--resume",
            os.path.join(c, "checkpoints", "step-000010"), "--dem-backend", "external",
            "--set", f'dem.command=["{{python}}", "{spheres}"]')
    print(f"swap: exit {r.returncode}: {r.stderr.strip()[-300:]}")
    check(r.returncode == 2 and 'taken with the DEM backend "cpu"' in r.stderr and
          "started" not in r.stdout, f"an external DEM resuming dem_server's checkpoint: "
          f"exit {r.returncode}: {r.stderr[-600:]}")


def case_badinput(demfem_run, source, d):
    text = open(scene_of(source)).read()
    no_command = os.path.join(d, "no_command.toml")
    with open(no_command, "w") as f:
        f.write(re.sub(r'^command = .*$', "", text, flags=re.M))
    r = run(demfem_run, no_command, os.path.join(d, "a"))
    print(f"no dem.command: exit {r.returncode}: {r.stderr.strip()[-300:]}")
    check(r.returncode == 2 and "dem.command" in r.stderr and "no_command.toml" in r.stderr,
          "a missing dem.command is not refused naming the file and key")
    r = run(demfem_run, scene_of(source), os.path.join(d, "b"), "--set",
            'dem.command=["./no_such_dem", "--fast"]')
    print(f"no such program: exit {r.returncode}: {r.stderr.strip()[-300:]}")
    check(r.returncode == 2 and "dem.command" in r.stderr and "no_such_dem" in r.stderr and
          "missing or not executable" in r.stderr, "a missing DEM program is not refused")
    r = run(demfem_run, scene_of(source), os.path.join(d, "c"), "--in-process")
    check(r.returncode == 2 and "dem.command" in r.stderr, f"--in-process: exit {r.returncode}")
    plate = os.path.join(source, "examples/python_spring_plate/static_ci.toml")
    r = run(demfem_run, plate, os.path.join(d, "e"), "--dem-backend", "external")
    print(f"--dem-backend external without dem.command: exit {r.returncode}: "
          f"{r.stderr.strip()[-300:]}")
    check(r.returncode == 2 and "command" in r.stderr, "--dem-backend external: no refusal")
    for k in "abce":
        check(not os.path.exists(os.path.join(d, k, "coupling.csv")), f"{k}: output written")


def case_faults(demfem_run, source, d):
    faulty = os.path.join(source, "tests/protocol/python/misbehaving_dem.py")
    expect = {
        "wrong-role": (1, "ended with status 4 before it attached"),
        "raise-in-step": (1, "the contact search lost a sphere"),
        "nan-force": (3, "the force it wrote for interface node 12 is not finite"),
        "die-in-step": (4, "dem solver died"),
    }
    for fault, (code, text) in expect.items():
        r = run(demfem_run, scene_of(source), os.path.join(d, fault), "--set",
                f'dem.command=["{{python}}", "{faulty}", "--fault", "{fault}"]',
                "--set", "run.end_time=0.002", "--set", "checkpoint.max_retries=1")
        lines = r.stderr.strip().splitlines()
        named = [m for m in lines if "DEM" in m and ("misbehaving_dem.py" in m or
                                                    'its backend "spheres (python' in m)]
        print(f"{fault}: exit {r.returncode}: {named[-1][:400] if named else lines[-1:]}")
        check(r.returncode == code, f"{fault}: exit {r.returncode}, expected {code}")
        check(any(text in m for m in named) or (text in r.stderr and named),
              f"{fault}: no message naming the external DEM backend with '{text}'")
        if fault == "wrong-role":
            check("DEMFEM_ROLE=dem" in r.stderr and "serves the fem side" in r.stderr,
                  "wrong-role: the program's refusal is not shown")
        if fault == "die-in-step":
            check("the DEM solver kept failing" in r.stderr and "restarting it" in r.stderr,
                  "die-in-step: not restarted, or the give-up not reported")
        if fault == "nan-force":
            csv_file = os.path.join(d, fault, "coupling.csv")
            check(os.path.exists(csv_file) and
                  all(int(x["step"]) < 3 for x in rows(os.path.join(d, fault))),
                  "nan-force: the step with the NaN force went on to the FEM")

    # A live DEM that does not answer a step: killed after checkpoint.reply_timeout and
    # restarted from the checkpoint, as dem_server; the run then equals the uninterrupted one.
    fault = "hang-in-step"
    short = ["--set", "run.end_time=0.002"]
    a = os.path.join(d, "straight")
    ra = run(demfem_run, scene_of(source), a, *short)
    r = run(demfem_run, scene_of(source), os.path.join(d, fault), *short, "--set",
            f'dem.command=["{{python}}", "{faulty}", "--fault", "{fault}"]',
            "--set", "checkpoint.reply_timeout=2")
    print(f"{fault}: exit {r.returncode}")
    if check(r.returncode == 0 and ra.returncode == 0, f"{fault}: exit {r.returncode}: "
             f"{r.stderr[-800:]}"):
        check("no reply within reply_timeout" in r.stderr and "restarting it" in r.stderr,
              f"{fault}: the hung DEM was not restarted: {r.stderr[-800:]}")
        keys = ["step", "time", "work_dem", "work_fem", "kinetic_energy", "force_sum_z"]
        check(all(x[k] == y[k] for x, y in zip(rows(a), rows(os.path.join(d, fault)))
                  for k in keys) and len(rows(a)) == 20, f"{fault}: the run differs")


CASES = {"coupled": case_coupled, "restart": case_restart, "badinput": case_badinput,
         "faults": case_faults}


if __name__ == "__main__":
    sys.exit(checks.main(CASES, "examples/python_dem_spheres"))
