"""ctest checks of liggghts_dem, LIGGGHTS as demfem's DEM (examples/liggghts_dem, issue 36).

  beam      cases/beam_fixed_ci.toml (160 spheres, 51 kg, on the clamped beam, one-way static)
            with dem_server, and examples/liggghts_dem/beam_fixed_ci.toml (the same spheres in
            a LIGGGHTS deck, the same Hertz contact) on 1 and 2 MPI ranks: the interface
            carries the spheres' weight m g (an independent reference) within 1e-6; the coupled
            mid-span deflection equals pure FEM's (the beam check) within 0.01 %; LIGGGHTS's
            deflections (probe and largest) equal dem_server's within 1e-6 relative and those
            of 1 and 2 ranks within 1e-9
  moving    examples/liggghts_dem/beam_spheres_ci.toml (five 2 kg spheres dropped on the dynamic
            beam, just in time: LIGGGHTS's mesh moves with the beam every coupling step) on 1
            and 2 ranks: at rest the interface carries their weight within 1e-5, their overlap
            with the moved surface is Hertz's static overlap under it within 1e-4 (against the
            unmoved surface it would be 27 % less), and 1 and 2 ranks give the same run
            (every coupling step's force and deflection within 1e-12)
  restart   the same scene to 15 ms, liggghts_dem (one rank, started without mpirun) killed in
            coupling step 145 (the spheres back on the beam after their first bounce):
            restarted from the step-140 checkpoint
            (a LIGGGHTS restart file that the deck reads), and coupling.csv equals the
            uninterrupted run's in every value column, bitwise
  srun      (under tests/sweep/slurm_cluster.sh, the sweep tests' one-node Slurm)
            beam_spheres_ci.toml to 5 ms with liggghts_dem on 2 ranks started by
            `srun -n 2 --mpi=pmix` against the program alone on one rank: LIGGGHTS runs on 2
            ranks, every coupling step's force and deflection within 1e-12, no job left in
            squeue, no segment in /dev/shm
  badinput  a deck without the coupling mesh, a dem.external.mesh_fix that names no fix, a deck
            whose wall keeps no contacts, polyhedra (dem.shapes), LIGGGHTS errors mid-run
            (atoms lost; a deck command that fails at LIGGGHTS step 1200): each a clear
            message (mid-run: the coupling step and LIGGGHTS's ERROR line), a non-zero exit
            status (1 mid-run)
  rankdeath rank 1 of `mpirun -np 2` SIGKILLed mid-run (beam_spheres_ci): mpirun ends, the
            launcher restarts the DEM from the last checkpoint, which LIGGGHTS 3.8 cannot read
            on 2 ranks: a clear refusal naming the way out, exit 1, within 180 s (no hung
            mpirun), no rank left running, no segment and no Open MPI shared-memory file
            (vader_segment.*) of the job left in /dev/shm

Usage: test_liggghts_dem.py CASE DEMFEM_RUN SOURCE_DIR LIGGGHTS_DEM. Exits 77 (skipped, saying
why) where liggghts_dem was not built (no libliggghts-dev or MPI) or mpirun is missing.
Nothing may be left in /dev/shm.
"""

import csv
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

failures = []
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1")


def check(ok, what):
    if not ok:
        failures.append(what)
    return ok


def run(demfem_run, scene, out, *extra):
    r = subprocess.run([demfem_run, scene, "--output-dir", out, *extra], capture_output=True,
                       text=True, errors="replace", timeout=400, env=ENV)
    for seg in re.findall(r"segment /(demfem-[0-9a-f]+)", r.stdout):
        check(not any(f.startswith(seg) for f in os.listdir("/dev/shm")),
              f"segment {seg} left in /dev/shm")
    return r


def last_row(out):
    with open(os.path.join(out, "coupling.csv")) as f:
        return list(csv.DictReader(f))[-1]


def beam_check(out):
    with open(os.path.join(out, "beam_check.csv")) as f:
        return {k: float(v) for k, v in next(csv.DictReader(f)).items()}


def liggghts_command(program, ranks):
    return f'dem.command=["mpirun", "-np", "{ranks}", "{program}"]'


def case_beam(demfem_run, source, program, tmp):
    results = {}
    r = run(demfem_run, os.path.join(source, "cases/beam_fixed_ci.toml"), f"{tmp}/dem_server")
    if not check(r.returncode == 0, f"dem_server run: exit {r.returncode}\n{r.stderr[-2000:]}"):
        return
    results["dem_server"] = (beam_check(f"{tmp}/dem_server"), last_row(f"{tmp}/dem_server"))
    scene = os.path.join(source, "examples/liggghts_dem/beam_fixed_ci.toml")
    for ranks in (1, 2):
        out = f"{tmp}/liggghts_{ranks}"
        r = run(demfem_run, scene, out, "--set", liggghts_command(program, ranks))
        if not check(r.returncode == 0, f"LIGGGHTS on {ranks} ranks: exit {r.returncode}\n"
                     f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}"):
            return
        check(f"{ranks} by 1 by 1 MPI processor grid" in r.stdout + r.stderr,
              f"LIGGGHTS did not run on {ranks} ranks")
        results[ranks] = (beam_check(out), last_row(out))
    weight = 51.0 * 9.81
    for name, (bc, row) in results.items():
        load = -float(row["force_sum_z"])
        check(abs(load - weight) < 1e-6 * weight, f"{name}: interface load {load} N, m g {weight}")
        rel = abs(bc["coupled"] - bc["fem_pressure"]) / abs(bc["fem_pressure"])
        check(rel < 1e-4, f"{name}: coupled deflection {bc['coupled']} vs pure FEM "
              f"{bc['fem_pressure']} ({rel:.2e})")
        print(f"{name}: load {load:.9g} N, mid-span {bc['coupled']:.10e} m (pure FEM "
              f"{bc['fem_pressure']:.10e}), largest {float(row['fem_max_displacement']):.10e} m")
    ref_bc, ref_row = results["dem_server"]

    def compare(a, b, tol, what):
        for key, x, y in (("mid-span", a[0]["coupled"], b[0]["coupled"]),
                          ("largest", float(a[1]["fem_max_displacement"]),
                           float(b[1]["fem_max_displacement"]))):
            check(abs(x - y) <= tol * abs(y), f"{what}: {key} deflection {x} vs {y}")
    compare(results[1], results["dem_server"], 1e-6, "LIGGGHTS 1 rank vs dem_server")
    compare(results[2], results[1], 1e-9, "LIGGGHTS 2 ranks vs 1 rank")


def rows(out):
    with open(os.path.join(out, "coupling.csv")) as f:
        return list(csv.DictReader(f))


def case_moving(demfem_run, source, program, tmp):
    scene = os.path.join(source, "examples/liggghts_dem/beam_spheres_ci.toml")
    series = {}
    for ranks in (1, 2):
        out = f"{tmp}/liggghts_{ranks}"
        r = run(demfem_run, scene, out, "--set", liggghts_command(program, ranks))
        if not check(r.returncode == 0, f"{ranks} ranks: exit {r.returncode}\n"
                     f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}"):
            return
        series[ranks] = rows(out)
    end = series[1][-1]
    weight, load = 5 * 2.0 * 9.81, -float(end["force_sum_z"])
    check(abs(load - weight) < 1e-5 * weight, f"interface load at rest {load} N, weight {weight}")
    # Hertz: F = 4/3 E* sqrt(R) d^1.5 per sphere, E* = E / (2 (1 - nu^2)) for two steels.
    e_star = 210e9 / (2 * (1 - 0.3 ** 2))
    hertz = (3 * 2.0 * 9.81 / (4 * e_star * 0.02 ** 0.5)) ** (2 / 3)
    overlap = float(end["max_overlap"])
    check(abs(overlap - hertz) < 1e-4 * hertz, f"overlap at rest {overlap} m, Hertz {hertz} m")
    deflection = float(end["fem_max_displacement"])
    print(f"at rest: load {load:.9g} N (weight {weight}), overlap {overlap:.6e} m (Hertz "
          f"{hertz:.6e}), beam's largest displacement {deflection:.6e} m")
    worst = 0.0
    for a, b in zip(series[1], series[2]):
        for key in ("force_sum_z", "fem_max_displacement"):
            x, y = float(a[key]), float(b[key])
            worst = max(worst, abs(x - y) / max(abs(x), 1e-300))
    check(len(series[1]) == len(series[2]) and worst <= 1e-12,
          f"1 and 2 ranks differ: {worst:.3e} relative")
    print(f"1 vs 2 ranks: largest relative difference {worst:.3e} over {len(series[1])} steps")


def case_restart(demfem_run, source, program, tmp):
    scene = os.path.join(source, "examples/liggghts_dem/beam_spheres_ci.toml")
    common = ["--set", "run.end_time=0.015", "--set", f'dem.command=["{program}"]']
    ra = run(demfem_run, scene, f"{tmp}/straight", *common)
    rb = run(demfem_run, scene, f"{tmp}/killed", *common, "--debug-kill", "dem:145")
    if not (check(ra.returncode == 0, f"uninterrupted run: exit {ra.returncode}\n"
                  f"{ra.stdout[-2000:]}\n{ra.stderr[-2000:]}") and
            check(rb.returncode == 0, f"killed run: exit {rb.returncode}\n"
                  f"{rb.stdout[-2000:]}\n{rb.stderr[-2000:]}")):
        return
    text = rb.stdout + rb.stderr
    check("recovered: every process is back at step 140" in text,
          f"no recovery from step 140 reported: {text[-1500:]}")
    keys = ["step", "time", "drift", "work_dem", "work_fem", "max_overlap", "kinetic_energy",
            "fem_max_displacement", "force_sum_z", "energy_error"]
    xa, xb = rows(f"{tmp}/straight"), rows(f"{tmp}/killed")
    check(len(xa) == len(xb) == 150, f"rows {len(xa)} and {len(xb)}, expected 150")
    check(len(xa) > 145 and float(xa[145]["force_sum_z"]) < -50.0,
          "the spheres were not on the beam when it was killed")
    differing = [(a["step"], k) for a, b in zip(xa, xb) for k in keys if a[k] != b[k]]
    check(not differing, f"the recovered run differs from the uninterrupted one: {differing[:5]}")
    print(f"restart: killed in step 145, recovered from step 140, final force "
          f"{xb[-1]['force_sum_z']} N, {len(differing)} values differ")


def case_srun(demfem_run, source, program, tmp):
    if not check(os.environ.get("SLURM_CONF"), "SLURM_CONF is not set: run under "
                 "tests/sweep/slurm_cluster.sh"):
        return
    scene = os.path.join(source, "examples/liggghts_dem/beam_spheres_ci.toml")
    short = ("--set", "run.end_time=0.005")
    series = {}
    for name, command in (("alone", f'dem.command=["{program}"]'),
                          ("srun", f'dem.command=["srun", "-n", "2", "--mpi=pmix", '
                                   f'"{program}"]')):
        out = f"{tmp}/{name}"
        r = run(demfem_run, scene, out, *short, "--set", command)
        if not check(r.returncode == 0, f"{name}: exit {r.returncode}\n"
                     f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}"):
            return
        series[name] = rows(out)
        grid = "2 by 1 by 1 MPI processor grid" if name == "srun" else "1 by 1 by 1"
        check(grid in r.stdout + r.stderr, f"{name}: LIGGGHTS did not report '{grid}'")
    worst = 0.0
    for a, b in zip(series["alone"], series["srun"]):
        for key in ("force_sum_z", "fem_max_displacement"):
            x, y = float(a[key]), float(b[key])
            worst = max(worst, abs(x - y) / max(abs(x), 1e-300))
    check(len(series["alone"]) == len(series["srun"]) == 50 and worst <= 1e-12,
          f"srun -n 2 and one rank differ: {worst:.3e} relative, "
          f"{len(series['alone'])} and {len(series['srun'])} rows")
    # srun's job is gone once Slurm has completed it: a job can still be listed as
    # completing (CG) for a moment after its step ended (slurmd cleans up), so wait for the
    # queue to empty (a hang guard, not a speed budget), and fail on a job that stays
    jobs = "?"
    for _ in range(120):
        jobs = subprocess.run(["squeue", "-h"], capture_output=True, text=True).stdout.strip()
        if not jobs:
            break
        time.sleep(0.5)
    check(not jobs, f"Slurm jobs left after 60 s: {jobs}")
    print(f"srun -n 2 vs one rank: largest relative difference {worst:.3e} over "
          f"{len(series['srun'])} steps")


def ranks_of(tag):
    """{rank: (pid, Open MPI job id)} of the liggghts_dem processes started with DEMFEM_TEST_TAG."""
    found = {}
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/environ", "rb") as f:
                env = dict(e.split(b"=", 1) for e in f.read().split(b"\0") if b"=" in e)
        except OSError:
            continue
        if env.get(b"DEMFEM_TEST_TAG") == tag.encode() and b"OMPI_COMM_WORLD_RANK" in env:
            found[int(env[b"OMPI_COMM_WORLD_RANK"])] = (int(pid),
                                                         int(env.get(b"OMPI_MCA_ess_base_jobid", 0)))
    return found


def case_rankdeath(demfem_run, source, program, tmp):
    scene = os.path.join(source, "examples/liggghts_dem/beam_spheres_ci.toml")
    out = f"{tmp}/killed"
    tag = f"rankdeath-{os.getpid()}"
    env = dict(ENV, DEMFEM_TEST_TAG=tag)
    p = subprocess.Popen([demfem_run, scene, "--output-dir", out, "--set", "run.end_time=2",
                          "--set", liggghts_command(program, 2)], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, errors="replace", env=env,
                         start_new_session=True)
    victim = None
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and p.poll() is None:
        try:
            with open(os.path.join(out, "coupling.csv")) as f:
                done = sum(1 for _ in f) - 1
        except OSError:
            done = 0
        ranks = ranks_of(tag)
        if done >= 25 and 1 in ranks:  # past the checkpoints of steps 10 and 20
            victim = ranks[1]
            os.kill(victim[0], signal.SIGKILL)
            break
        time.sleep(0.05)
    if not check(victim is not None, "rank 1 was not found running past coupling step 25"):
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return
    try:
        text, _ = p.communicate(timeout=180)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        text, _ = p.communicate()
        check(False, "demfem run did not end within 180 s of the kill (a hung mpirun?)")
    check(p.returncode == 1, f"exit {p.returncode}, expected 1:\n{text[-3000:]}")
    # The kill lands in a step or, now and then, while the DEM writes a checkpoint (every 10
    # steps, from step 30 on): both are reported as the DEM's death.
    for pattern in (r"the DEM solver failed (in coupling step \d+ .*2 MPI ranks|\(the DEM solver "
                    r"failed writing checkpoint \S+/step-\d+/dem\.h5).*dem solver died",
                    r"restart 1 of 3, rolling back to checkpoint",
                    r"cannot restore .*dem\.h5 on 2 MPI ranks: LIGGGHTS 3\.8's read_restart .*"
                    r"resume on one rank"):
        check(re.search(pattern, text) is not None, f"no /{pattern}/ in:\n{text[-3000:]}")
    for seg in re.findall(r"segment /(demfem-[0-9a-f]+)", text):
        check(not any(f.startswith(seg) for f in os.listdir("/dev/shm")),
              f"segment {seg} left in /dev/shm")
    time.sleep(1)
    check(not ranks_of(tag), f"liggghts_dem ranks left running: {ranks_of(tag)}")
    job = f".{victim[1]:x}."  # Open MPI's vader_segment.<host>.<job id, hex>.<local rank>
    left = [f for f in os.listdir("/dev/shm") if f.startswith("vader_segment") and job in f]
    check(victim[1] != 0 and not left, f"Open MPI shared-memory files left: {left}")
    # What the launcher removed after the job (mpirun's clean-up races with its exit).
    for line in text.splitlines():
        if "removed /dev/shm/" in line:
            print(line)
    print(f"rank 1 (pid {victim[0]}) killed: exit {p.returncode}, nothing left in /dev/shm")


def expect_refusal(demfem_run, scene, out, what, pattern, *extra, code=None):
    r = run(demfem_run, scene, out, *extra)
    text = r.stdout + r.stderr
    if check(r.returncode != 0, f"{what}: exit 0"):
        check(re.search(pattern, text) is not None,
              f"{what}: exit {r.returncode}, no /{pattern}/ in:\n{text[-3000:]}")
    if code is not None:
        # A deck refused in the handshake is bad input (2), and the launcher blames the DEM,
        # not the FEM whose turn the mesh exchange began with (it did both before).
        check(r.returncode == code, f"{what}: exit {r.returncode}, expected {code}")
        check(re.search(r"the external DEM backend .* reported an error in its handshake",
                        text) is not None, f"{what}: the DEM is not named:\n{text[-2000:]}")
    print(f"{what}: exit {r.returncode}")
    return r


def case_badinput(demfem_run, source, program, tmp):
    folder = os.path.join(source, "examples/liggghts_dem")
    for name in ("beam_fixed_ci.toml", "beam_fixed_ci.liggghts"):
        shutil.copy(os.path.join(folder, name), tmp)
    scene = os.path.join(tmp, "beam_fixed_ci.toml")
    with open(os.path.join(folder, "beam_fixed_ci.liggghts")) as f:
        deck = f.read()
    command = liggghts_command(program, 1)

    def variant(name, text):
        with open(os.path.join(tmp, name), "w") as f:
            f.write(text)
        return f'dem.external.deck="{name}"'

    no_mesh = "\n".join(l for l in deck.splitlines() if "demfem_surface" not in l)
    expect_refusal(demfem_run, scene, f"{tmp}/no_mesh", "a deck without the coupling mesh",
                   r"has no fix 'demfem_surface' \(dem.external.mesh_fix\).*mesh fixes: none",
                   "--set", command, "--set", variant("no_mesh.liggghts", no_mesh), code=2)
    expect_refusal(demfem_run, scene, f"{tmp}/wrong_id", "a mesh ID that does not exist",
                   r"has no fix 'no_such_mesh'.*mesh fixes: demfem_surface \(mesh/surface\)",
                   "--set", command, "--set", 'dem.external.mesh_fix="no_such_mesh"', code=2)
    no_contacts = deck.replace(" store_force_contact_stress yes", "")
    expect_refusal(demfem_run, scene, f"{tmp}/no_contacts", "a wall that keeps no contacts",
                   r"add `store_force_contact_stress yes`", "--set", command, "--set",
                   variant("no_contacts.liggghts", no_contacts))
    # Gravity upwards, 1000 g: the spheres leave the box (z = 0.2 m) after about 4 ms, and
    # LIGGGHTS stops with "Lost atoms" (the deck's thermo_modify lost error) at the end of
    # that coupling step's run.
    lost = deck.replace("gravity 9.81 vector 0.0 0.0 -1.0", "gravity 9810 vector 0.0 0.0 1.0")
    r = expect_refusal(demfem_run, scene, f"{tmp}/lost", "a LIGGGHTS error mid-run",
                       r"ERROR: Lost atoms", "--set", command, "--set",
                       variant("lost.liggghts", lost))
    check(re.search(r"the DEM solver failed in coupling step \d+ .*liggghts_dem \(LIGGGHTS",
                    r.stdout + r.stderr) is not None,
          "a LIGGGHTS error mid-run: the launcher does not name the step and the DEM backend")
    check(re.search(r"liggghts_dem: LIGGGHTS ended the DEM in coupling step \d+ .*ERROR: Lost "
                    r"atoms", r.stdout + r.stderr) is not None,
          "a LIGGGHTS error mid-run: the adapter does not name the step and LIGGGHTS's message")
    # A deck command that fails at LIGGGHTS step 1200, in coupling step 2 (n_D = 500): a
    # variable that names no variable, printed every 1200 steps (quoted: evaluated then).
    failing = deck + ('\nvariable bad equal "step*v_no_such_variable"\n'
                      'fix fail all print 1200 "${bad}"\n')
    r = expect_refusal(demfem_run, scene, f"{tmp}/step_k", "a LIGGGHTS error at step k",
                       r"liggghts_dem: LIGGGHTS ended the DEM in coupling step 2 \(t = 0\.002 "
                       r"s\): ERROR: Invalid variable name in variable formula", "--set", command,
                       "--set", variant("step_k.liggghts", failing))
    check(r.returncode == 1, f"a LIGGGHTS error at step k: exit {r.returncode}, expected 1")
    check("the DEM solver failed in coupling step 2 (t = 0.002 s)" in r.stdout + r.stderr,
          "a LIGGGHTS error at step k: the launcher does not name coupling step 2")
    with open(scene) as f:
        text = f.read()
    with open(os.path.join(tmp, "polyhedra.toml"), "w") as f:
        f.write(text + '\n[[dem.shapes]]\nname = "cube"\n')
    expect_refusal(demfem_run, os.path.join(tmp, "polyhedra.toml"), f"{tmp}/polyhedra",
                   "polyhedra", r"dem\.shapes.*dilated polyhedra are dem_server's", "--set",
                   command)


def main():
    case, demfem_run, source, program = sys.argv[1:5]
    if not program or not os.path.exists(program):
        print("skipped: liggghts_dem was not built (LIGGGHTS or MPI not found: ./demfem setup "
              "installs libliggghts-dev and openmpi-bin)")
        return 77
    if shutil.which("mpirun") is None:
        print("skipped: mpirun is not on PATH (openmpi-bin)")
        return 77
    tmp = tempfile.mkdtemp(prefix="demfem_liggghts_")
    try:
        {"beam": case_beam, "moving": case_moving, "restart": case_restart,
         "srun": case_srun, "rankdeath": case_rankdeath,
         "badinput": case_badinput}[case](demfem_run, source, program, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    for f in failures:
        print("FAILED:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
