"""ctest checks of the Python SDK (protocol/python) through real coupled runs: demfem_run starts
the minimal Python backend examples/python_spring_plate/spring_plate.py (fem.backend =
"external") beside dem_server.

  static        the settled spheres' weight gives the plate z = F_z / k exactly
  restart       the Python backend killed in step 15 is restarted from the last checkpoint
                like fem_server, and the run equals the uninterrupted one (coupling.csv)
  handshake     backends that exit before attaching, raise or die in their handshake are
                refused with a message naming the program and pid
  interface     a backend that reports another interface size when resumed or restarted is
                refused (exit 2 on --resume, 1 on a restart), naming it
  version       a backend that speaks another protocol version is refused, naming the program,
                its pid and both versions
  hang          a live backend that sleeps in step() or spins in restore_checkpoint() is
                killed after checkpoint.reply_timeout and restarted from the checkpoint (the
                run then equals the uninterrupted one), or the run gives up with exit 4, the
                hung process killed at once; a reply_timeout beyond 10^6 s is refused
  kinematics    a NaN position or an infinite velocity the backend writes is its blow-up
                (exit 3, naming the backend and the node), not the DEM's; complex diagnostics
                or complex values written into an interface array are refused (exit 1), and so
                is a published mesh with a NaN node, naming the FEM and the node
  elsewhere     the example with checkpoints run as documented from another folder, with the
                default output folder (relative to that folder): checkpoints and a restart

Usage: test_python_sdk.py CASE DEMFEM_RUN SOURCE_DIR. Nothing may be left in /dev/shm.
"""

import os
import re
import sys
import time

import coupled_checks as checks  # beside this file
from coupled_checks import check, rows, run


def case_static(demfem_run, source, d):
    r = run(demfem_run, os.path.join(source, "examples/python_spring_plate/static_ci.toml"), d)
    if not check(r.returncode == 0, f"static run failed ({r.returncode}): {r.stderr[-2000:]}"):
        return
    last = rows(d)[-1]
    f, z = float(last["force_sum_z"]), float(last["fem_max_displacement"])
    print(f"static: F_z = {f!r} N, plate z = {z!r} m, F_z / k = {abs(f) / 1e7!r} m")
    check(abs(f + 51.0 * 9.81) < 1e-6 * 500, f"the settled weight is {f} N, not 51 kg x 9.81")
    check(abs(z - abs(f) / 1e7) <= 1e-15 * z, f"plate z = {z}, F_z / k = {abs(f) / 1e7}")


def case_restart(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml")
    a, b = os.path.join(d, "straight"), os.path.join(d, "killed")
    ra = run(demfem_run, scene, a)
    rb = run(demfem_run, scene, b, "--debug-kill", "fem:15")
    if not (check(ra.returncode == 0, f"uninterrupted run failed: {ra.stderr[-2000:]}") and
            check(rb.returncode == 0, f"killed run failed: {rb.stderr[-2000:]}")):
        return
    check("restarting it" in rb.stderr and "recovered" in rb.stderr,
          f"no restart reported: {rb.stderr[-1500:]}")
    check("started the external FEM backend" in rb.stdout, "the restart did not start the backend")
    keys = ["step", "time", "drift", "work_dem", "work_fem", "max_overlap", "kinetic_energy",
            "fem_max_displacement", "force_sum_z"]
    xa, xb = rows(a), rows(b)
    check(len(xa) == len(xb) == 40, f"rows {len(xa)} and {len(xb)}, expected 40")
    same = all(ra_[k] == rb_[k] for ra_, rb_ in zip(xa, xb) for k in keys)
    check(same, "the restarted run differs from the uninterrupted one")
    print(f"restart: 40 steps, final plate displacement {xb[-1]['fem_max_displacement']} m in both")


def case_handshake(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/static_ci.toml")
    faulty = os.path.join(source, "tests/protocol/python/misbehaving_backend.py")
    expect = {
        "exit-before-attach": (1, "ended with status 3 before it attached"),
        "raise-in-mesh": (1, "reported an error in its handshake"),
        "die-in-mesh": (1, "ended with status 7 before it attached"),
    }
    for fault, (code, text) in expect.items():
        r = run(demfem_run, scene, os.path.join(d, fault), "--set",
                f'fem.command=["{{python}}", "{faulty}", "--fault", "{fault}"]', env=checks.ENV)
        msg = r.stderr.strip().splitlines()
        named = [m for m in msg if "external FEM backend" in m and "misbehaving_backend.py" in m]
        print(f"{fault}: exit {r.returncode}: {named[-1][:300] if named else msg[-1:]}")
        check(r.returncode == code, f"{fault}: exit {r.returncode}, expected {code}")
        check(any(text in m for m in named), f"{fault}: no message naming the backend with '{text}'")
        check(re.search(r"pid [0-9]+", " ".join(named)) is not None, f"{fault}: pid not named")
    r = run(demfem_run, scene, os.path.join(d, "raise"), "--set",
            f'fem.command=["{{python}}", "{faulty}", "--fault", "raise-in-mesh"]', env=checks.ENV)
    check("ValueError: the mesh file is broken" in r.stderr, "the Python exception text is lost")


def case_interface(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml")
    faulty = os.path.join(source, "tests/protocol/python/misbehaving_backend.py")
    cmd = f'fem.command=["{{python}}", "{faulty}", "--fault", "other-size-on-resume"]'
    out = os.path.join(d, "a")
    r = run(demfem_run, scene, out, "--set", cmd, env=checks.ENV)
    if not check(r.returncode == 0, f"first run failed: {r.stderr[-1500:]}"):
        return
    r = run(demfem_run, scene, out, "--set", cmd, "--resume", env=checks.ENV)
    line = [m for m in r.stderr.splitlines() if "reports an interface of 33 nodes" in m]
    print(f"resume: exit {r.returncode}: {line[-1][:300] if line else r.stderr[-300:]}")
    check(r.returncode == 2, f"resume with another interface: exit {r.returncode}, expected 2")
    check(bool(line) and "external FEM backend" in line[-1] and "has 63" in line[-1],
          "resume: the refusal does not name the backend and both sizes")
    r = run(demfem_run, scene, os.path.join(d, "b"), "--set", cmd, "--debug-kill", "fem:15",
            env=checks.ENV)
    line = [m for m in r.stderr.splitlines() if "was refused" in m]
    print(f"restart: exit {r.returncode}: {line[-1][:300] if line else r.stderr[-300:]}")
    check(r.returncode == 1, f"restart with another interface: exit {r.returncode}, expected 1")
    check(bool(line) and "external FEM backend" in line[-1] and "33 interface nodes" in line[-1],
          "restart: the refusal does not name the backend and the size")


def case_version(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/static_ci.toml")
    other = os.path.join(source, "tests/protocol/python/other_version_backend.py")
    r = run(demfem_run, scene, os.path.join(d, "v"), "--set",
            f'fem.command=["{{python}}", "{other}"]', env=checks.ENV)
    line = [m for m in r.stderr.splitlines() if "protocol version mismatch" in m
            and "external FEM backend" in m]
    print(f"version: exit {r.returncode}: {line[-1][:300] if line else r.stderr[-600:]}")
    check(r.returncode == 1, f"another protocol version: exit {r.returncode}, expected 1")
    check(bool(line), "the refusal does not name the external FEM backend")
    if line:
        check("other_version_backend.py" in line[-1], "the program is not named")
        check(re.search(r"pid [0-9]+", line[-1]) is not None, "the pid is not named")
        check("speaks protocol version 999" in line[-1], "the backend's version is not named")
    check("refusing to attach" in r.stderr, "the backend's own refusal is lost")
    check(not os.path.exists(os.path.join(d, "v", "coupling.csv")) or
          len(open(os.path.join(d, "v", "coupling.csv")).read().splitlines()) <= 1,
          "the refused run wrote coupling steps")


KEYS = ["step", "time", "drift", "work_dem", "work_fem", "max_overlap", "kinetic_energy",
        "fem_max_displacement", "force_sum_z"]


def same_rows(a, b):
    xa, xb = rows(a), rows(b)
    return len(xa) == len(xb) == 40 and all(p[k] == q[k] for p, q in zip(xa, xb) for k in KEYS)


def case_hang(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml")
    faulty = os.path.join(source, "tests/protocol/python/misbehaving_backend.py")
    # A limit beyond 10^6 s is refused (in milliseconds it did not fit the wait's clock).
    r = run(demfem_run, scene, os.path.join(d, "huge"), "--set", "checkpoint.reply_timeout=1e300")
    check(r.returncode == 2 and "'checkpoint.reply_timeout'" in r.stderr and
          "outside the accepted range [0, 1e+06]" in r.stderr and "started" not in r.stdout,
          f"reply_timeout = 1e300: exit {r.returncode}: {r.stderr[-1000:]}")
    ref = os.path.join(d, "straight")
    r = run(demfem_run, scene, ref)
    if not check(r.returncode == 0, f"uninterrupted run failed: {r.stderr[-2000:]}"):
        return
    # The backend sleeps an hour (or spins forever); reply_timeout = 2 s finds it (1 s would
    # do, but a checkpoint's fsync on a loaded machine may take a second).
    expect = {"hang-in-step": 0, "spin-in-restore-once": 0, "spin-in-restore": 4}
    for fault, code in expect.items():
        out = os.path.join(d, fault)
        t0 = time.monotonic()
        r = run(demfem_run, scene, out, "--set", "checkpoint.reply_timeout=2", "--set",
                "checkpoint.max_retries=2", "--set",
                f'fem.command=["{{python}}", "{faulty}", "--fault", "{fault}"]', env=checks.ENV)
        secs = time.monotonic() - t0
        restarts = len(re.findall(r"FEM solver failed \(.*no reply within reply_timeout "
                                  r"\(2000 ms\).*\); restart [12] of 2", r.stderr))
        print(f"{fault}: exit {r.returncode} after {secs:.1f} s, {restarts} restarts")
        check(r.returncode == code, f"{fault}: exit {r.returncode}, expected {code}: "
                                    f"{r.stderr[-2000:]}")
        check(secs < 120.0, f"{fault}: the run took {secs:.0f} s (the backend hangs an hour)")
        check(restarts == (1 if fault == "hang-in-step" else 2),
              f"{fault}: {restarts} restarts after a reply timeout: {r.stderr[-2000:]}")
        if code == 0:
            check("recovered: every process is back at step 10" in r.stderr,
                  f"{fault}: no recovery to step 10 reported")
            check(same_rows(ref, out), f"{fault}: the recovered run differs from the "
                                       "uninterrupted one")
        else:
            check("kept failing: 2 restarts from checkpoint" in r.stderr,
                  f"{fault}: no report of the given-up recovery")
            # The third process, spinning in restore_checkpoint(), is killed at once: it would
            # answer neither Shutdown nor SIGTERM (seconds of waiting for both).
            check("the FEM solver (pid" in r.stderr and "is not answering: killed" in r.stderr,
                  f"{fault}: the spinning process was not killed at once: {r.stderr[-1000:]}")
    # The handshake: a restarted process that sleeps before its Hello is killed after
    # --hello-timeout and started again, as one that hangs in a step.
    t0 = time.monotonic()
    r = run(demfem_run, scene, os.path.join(d, "mesh"), "--hello-timeout", "5", "--set",
            "checkpoint.reply_timeout=2", "--set", "checkpoint.max_retries=2", "--set",
            f'fem.command=["{{python}}", "{faulty}", "--fault", "hang-in-mesh-on-resume"]',
            env=checks.ENV)
    secs = time.monotonic() - t0
    print(f"hang-in-mesh-on-resume: exit {r.returncode} after {secs:.1f} s")
    check(r.returncode == 4, f"hang in the handshake: exit {r.returncode}: {r.stderr[-2000:]}")
    check("no Hello within 5000 ms" in r.stderr and "restart 2 of 2" in r.stderr,
          f"hang in the handshake: no Hello timeout and second restart: {r.stderr[-2000:]}")
    check("is not answering: killed" in r.stderr, "hang in the handshake: the process left")
    check(secs < 120.0, f"hang in the handshake: the run took {secs:.0f} s")


def case_kinematics(demfem_run, source, d):
    scene = os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml")
    faulty = os.path.join(source, "tests/protocol/python/misbehaving_backend.py")
    expect = {
        ("nan-position", "just_in_time"): (3, ["position", "interface node 3", "not finite"]),
        ("nan-position", "predictive"): (3, ["position", "interface node 3", "not finite"]),
        ("inf-velocity", "just_in_time"): (3, ["velocity", "interface node 7", "inf"]),
        ("complex-return", "just_in_time"): (1, ["complex numbers", "complex128"]),
        ("complex-write", "just_in_time"): (1, ["cast complex numbers to real"]),
    }
    for (fault, scheme), (code, texts) in expect.items():
        r = run(demfem_run, scene, os.path.join(d, fault + scheme), "--set",
                f'coupling.scheme="{scheme}"', "--set",
                f'fem.command=["{{python}}", "{faulty}", "--fault", "{fault}"]', env=checks.ENV)
        last = r.stderr.strip().splitlines()[-3:]
        print(f"{fault} ({scheme}): exit {r.returncode}: {' | '.join(last)[:400]}")
        check(r.returncode == code, f"{fault} ({scheme}): exit {r.returncode}, expected {code}")
        blamed = "FEM solver failed in coupling step 5" in r.stderr and "DEM solver" not in r.stderr
        check(blamed, f"{fault} ({scheme}): the FEM in step 5 is not blamed: {r.stderr[-1500:]}")
        if code == 3:  # the coupler's own check names the backend (Hello's name)
            check('its backend "spring-plate' in r.stderr,
                  f"{fault} ({scheme}): the backend is not named")
        for t in texts:
            check(t in r.stderr, f"{fault} ({scheme}): '{t}' missing: {r.stderr[-1500:]}")
        check("restarting it" not in r.stderr, f"{fault} ({scheme}): the error was restarted")
    # A NaN node in the published mesh: refused at the handshake, naming the FEM and the node
    # (the DEM used to fail on it in step 0, blamed with exit 1).
    r = run(demfem_run, scene, os.path.join(d, "nan-mesh"), "--set",
            f'fem.command=["{{python}}", "{faulty}", "--fault", "nan-mesh"]', env=checks.ENV)
    line = [m for m in r.stderr.splitlines() if "published an interface mesh" in m]
    print(f"nan-mesh: exit {r.returncode}: {line[-1][:300] if line else r.stderr[-300:]}")
    check(r.returncode == 1, f"nan-mesh: exit {r.returncode}, expected 1")
    check(bool(line) and 'backend "spring-plate' in line[-1] and
          "node 4 is not finite: (nan, 0, 0.1) m" in line[-1] and "DEM solver" not in r.stderr,
          f"nan-mesh: the FEM and the node are not named: {r.stderr[-1500:]}")
    check(not os.path.exists(os.path.join(d, "nan-mesh", "coupling.csv")) or
          len(rows(os.path.join(d, "nan-mesh"))) == 0, "nan-mesh: the refused run took steps")


def case_elsewhere(demfem_run, source, d):
    # As docs/backends.md says to run it, but from another folder: run.output_dir (out/<name>)
    # is relative to that folder, and the backend runs in the scene's folder. Every path it is
    # given (output folder, checkpoint files) must be absolute.
    scene = os.path.relpath(os.path.join(source, "examples/python_spring_plate/dynamic_ci.toml"),
                            d)
    r = run(demfem_run, scene, None, "--debug-kill", "fem:15", cwd=d)
    out = os.path.join(d, "out", "spring_plate_dynamic_ci")
    print(f"elsewhere: exit {r.returncode}: {r.stderr.strip().splitlines()[-1:]}")
    check(r.returncode == 0, f"run from another folder: exit {r.returncode}: {r.stderr[-2000:]}")
    check("recovered: every process is back at step 10" in r.stderr, "no recovery reported")
    check(os.path.isfile(os.path.join(out, "checkpoints", "step-000040", "fem.h5")),
          "the last checkpoint has no fem.h5")
    check(len(rows(out)) == 40 if os.path.exists(os.path.join(out, "coupling.csv")) else False,
          "coupling.csv of 40 rows missing")
    check(not os.path.exists(os.path.join(source, "examples/python_spring_plate/out")),
          "the backend wrote into the scene's folder")
    r = run(demfem_run, scene, None, "--resume", "--set", "run.end_time=0.005", cwd=d)
    check(r.returncode == 0, f"--resume from another folder: exit {r.returncode}: "
                             f"{r.stderr[-2000:]}")


CASES = {"static": case_static, "restart": case_restart, "handshake": case_handshake,
         "interface": case_interface, "version": case_version, "hang": case_hang,
         "kinematics": case_kinematics, "elsewhere": case_elsewhere}
if __name__ == "__main__":
    sys.exit(checks.main(CASES, "examples/python_spring_plate"))
