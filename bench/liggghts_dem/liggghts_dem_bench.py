#!/usr/bin/python3
"""liggghts_dem: wall time per coupling step of both DEM backends on one sphere scene.

The scene: a bed of spheres (wheat of cases/sheet_ci.toml: d = 6 mm, E = 100 MPa, friction
1.0 among grains, 0.22 on steel, restitution 0.4) in a simple cubic lattice of touching
spheres (0.6 um apart) on the sheet CI case's steel plate (0.34 x 0.10 m, 0.75 mm, 34 x 10
MITC4 shells, clamped over x <= 0.06 m, its top surface coupled: 680 triangles), 10 um
above it: a bed as many grains as the sheet CI case's (5,565) that settles on the sheet and
bends it, coupled two-way (just in time, dt_F = 1e-4 s, dt_D = 2e-5 s: n_D = 5). The same spheres at the same places in
dem_server (a CSV bed) and in a LIGGGHTS deck (create_atoms), the same Hertz contact.

Variants, interleaved, --repeats times each: dem_server on 1 and 2 threads (dem.threads),
liggghts_dem on 1 and 2 MPI ranks (mpirun -np N). For each: the DEM's wall time per coupling
step as the coupler sees it (coupling.csv wall_dem: the DEM's step() and the message round
trip; median over the steps after the first 10), and for LIGGGHTS where it went
(liggghts_dem_times.json, rank 0's median coupling step of each part): LIGGGHTS's own loop, the fixed
cost of its `run ... pre no post no` commands, full set-ups, and the adapter's own work: the
mesh update (nodes written into LIGGGHTS's mesh, its geometry recomputed), the gather
(contact distribution, kinetic energy, overlap, the reduction onto rank 0), the broadcasts
and the protocol I/O. adapter_share = adapter / (adapter + LIGGGHTS), of the medians
(adapter_share_total: of the run's totals, which count every stall of a loaded machine):
the issue's goal is under 5 %.

Prints a table (medians and bests over the repeats), writes JSON (--json, default
./liggghts_dem.json in the current folder).

  liggghts_dem [--json FILE] [--repeats 3] [--end-time 0.04] [--layers 8]
"""

import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

SOURCE = Path("@PROJECT_SOURCE_DIR@")
BINARY = Path("@PROJECT_BINARY_DIR@")
if str(SOURCE).startswith("@"):  # run from the source tree
    SOURCE = Path(__file__).resolve().parents[2]
    BINARY = SOURCE / "build"
sys.path.insert(0, str(SOURCE / "bench" / "common"))
import bench_meta  # noqa: E402 (the machine and commit beside the figures)
DEMFEM_RUN = BINARY / "bin" / "demfem_run"
LIGGGHTS_DEM = BINARY / "bin" / "liggghts_dem"
# Open MPI as root, more ranks than free cores, and ranks that yield while they wait.
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_mpi_yield_when_idle="1")

DIAMETER = 0.006      # m
SPACING = 1.0001 * DIAMETER   # m, lattice pitch
SHEET_TOP = 0.000375  # m: the plate's top surface (mid-surface z = 0, 0.75 mm thick)
DENSITY = 1242.0      # kg/m^3, wheat
SKIP_STEPS = 10       # coupling steps left out of the medians (start-up)
ADAPTER_PARTS = ("mesh_update", "gather", "broadcast", "protocol_io")

COMMON = """[run]
name = "liggghts_dem_bench"
end_time = {end_time!r}

[coupling]
scheme = "just_in_time"
diagnostics_interval = 1

[fem]
analysis = "dynamic"
dt = 1e-4
interface_surface = "top"

[fem.mesh.plate]
origin = [0.0, 0.0, 0.0]
size = [0.34, 0.1]
cells = [34, 10]

[[fem.materials]]
name = "steel"
youngs_modulus = 1.85e11
poisson_ratio = 0.3
density = 7850.0

[[fem.sections]]
elements = "all"
material = "steel"
thickness = 0.00075

[[fem.clamps]]
nodes = "x <= 0.06"

[fem.bossak]
alpha = -0.1
gamma = 0.6
beta = 0.3025
"""

DEM_SERVER = """
[dem]
dt = 2e-5
threads = {threads}
interface_material = "steel"
skin = 0.0006

[[dem.materials]]
name = "wheat"
youngs_modulus = 1e8
poisson_ratio = 0.3
density = {density!r}

[[dem.materials]]
name = "steel"
youngs_modulus = 1.85e11
poisson_ratio = 0.3

[[dem.pairs]]
a = "wheat"
b = "wheat"
friction = 1.0
restitution = 0.4

[[dem.pairs]]
a = "wheat"
b = "steel"
friction = 0.22
restitution = 0.4

[dem.load]
file = "bed.csv"
material = "wheat"
outside = "keep"
"""

LIGGGHTS = """
[dem]
backend = "external"
command = ["mpirun", "-np", "{ranks}", "{program}"]
dt = 2e-5

[dem.external]
deck = "bed.liggghts"
mesh_fix = "demfem_surface"
"""

DECK_HEAD = """# bench/liggghts_dem: the bed of bed.csv in LIGGGHTS (the same spheres and contact law)
atom_style      granular
atom_modify     map array
boundary        f f f
newton          off
communicate     single vel yes
units           si
hard_particles  yes
region          domain block -0.01 0.35 -0.01 0.11 -0.05 0.08 units box
create_box      2 domain
neighbor        0.0006 bin
neigh_modify    delay 0
fix             m1 all property/global youngsModulus peratomtype 1e8 1.85e11
fix             m2 all property/global poissonsRatio peratomtype 0.3 0.3
fix             m3 all property/global coefficientRestitution peratomtypepair 2 0.4 0.4 0.4 0.4
fix             m4 all property/global coefficientFriction peratomtypepair 2 1.0 0.22 0.22 0.22
pair_style      gran model hertz tangential history
pair_coeff      * *
fix             demfem_surface all mesh/surface file ${demfem_mesh} type 2
fix             walls all wall/gran model hertz tangential history mesh n_meshes 1 meshes demfem_surface store_force_contact_stress yes
"""

DECK_TAIL = """set             group all diameter {diameter!r} density {density!r}
fix             gravity all gravity 9.81 vector 0.0 0.0 -1.0
fix             integrate all nve/sphere
thermo          1000
thermo_modify   lost error
"""


def lattice(layers):
    """Sphere centres: a simple cubic lattice over the free part of the plate."""
    points = []
    nx = int((0.34 - 0.065) / SPACING)
    ny = int((0.1 - 0.002) / SPACING)
    for k in range(layers):
        for j in range(ny):
            for i in range(nx):
                points.append((0.065 + SPACING * (i + 0.5), 0.001 + SPACING * (j + 0.5),
                               SHEET_TOP + 1e-5 + DIAMETER / 2 + SPACING * k))
    return points


def write_scenes(folder, points, end_time):
    with open(folder / "bed.csv", "w") as f:
        f.write("x,y,z,r\n")
        for p in points:
            f.write(f"{p[0]!r},{p[1]!r},{p[2]!r},{DIAMETER / 2!r}\n")
    with open(folder / "bed.liggghts", "w") as f:
        f.write(DECK_HEAD)
        for p in points:
            f.write(f"create_atoms 1 single {p[0]!r} {p[1]!r} {p[2]!r} units box\n")
        f.write(DECK_TAIL.format(diameter=DIAMETER, density=DENSITY))
    common = COMMON.format(end_time=end_time)
    for threads in (1, 2):
        (folder / f"dem_server_{threads}.toml").write_text(
            common + DEM_SERVER.format(threads=threads, density=DENSITY))
    for ranks in (1, 2):
        (folder / f"liggghts_{ranks}.toml").write_text(
            common + LIGGGHTS.format(ranks=ranks, program=LIGGGHTS_DEM))





def run_variant(folder, name, k):
    out = folder / f"{name}-{k}"
    r = subprocess.run([str(DEMFEM_RUN), str(folder / f"{name}.toml"), "--output-dir", str(out)],
                       capture_output=True, text=True, env=ENV, cwd=folder)
    if r.returncode != 0:
        sys.exit(f"liggghts_dem bench: {name} failed (exit {r.returncode}):\n"
                 f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    with open(out / "coupling.csv") as f:
        rows = list(csv.DictReader(f))[SKIP_STEPS:]
    row = {"variant": name, "repeat": k, "steps": len(rows),
           "wall_dem_ms": 1e3 * statistics.median(float(x["wall_dem"]) for x in rows),
           "wall_dem_mean_ms": 1e3 * statistics.fmean(float(x["wall_dem"]) for x in rows)}
    times = out / "liggghts_dem_times.json"
    if times.exists():
        t = json.loads(times.read_text())
        median = t["median_step_seconds"]
        for key, seconds in median.items():
            row[f"{key}_us"] = 1e6 * seconds
        row["set_ups"] = t["set_ups"]
        adapter = sum(median[k] for k in ADAPTER_PARTS)
        row["adapter_share"] = adapter / sum(median.values())
        row["adapter_share_total"] = t["adapter"] / (t["adapter"] + t["liggghts"])
    return row


def summarise(rows):
    out = {}
    for name in dict.fromkeys(r["variant"] for r in rows):
        mine = [r for r in rows if r["variant"] == name]
        keys = [k for k, v in mine[0].items() if isinstance(v, float)]
        out[name] = {k: {"median": statistics.median(r[k] for r in mine),
                         "best": min(r[k] for r in mine)} for k in keys}
    return out


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--json", default="liggghts_dem.json",
                   help="where the JSON goes (default: liggghts_dem.json in the current folder)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--end-time", type=float, default=0.04,
                   help="simulated time of each run, s (0.04: 400 coupling steps)")
    p.add_argument("--layers", type=int, default=8,
                   help="lattice layers of 45 x 16 spheres (8: 5760 spheres)")
    a = p.parse_args(argv)
    for exe in (DEMFEM_RUN, LIGGGHTS_DEM):
        if not exe.exists():
            sys.exit(f"liggghts_dem bench: {exe} not built (liggghts_dem needs libliggghts-dev "
                     "and openmpi-bin: ./demfem setup)")
    points = lattice(a.layers)
    variants = ["dem_server_1", "liggghts_1", "dem_server_2", "liggghts_2"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="demfem-liggghts-bench-") as tmp:
        folder = Path(tmp)
        write_scenes(folder, points, a.end_time)
        for k in range(a.repeats):
            for name in variants:
                rows.append(run_variant(folder, name, k))
    summary = summarise(rows)
    mass = len(points) * DENSITY * math.pi / 6 * DIAMETER ** 3
    info = {"spheres": len(points), "mass_kg": mass, "coupling_steps": rows[0]["steps"],
            "n_D": 5, "triangles": 680, "goal": "adapter_share < 0.05"}
    machine, commit = bench_meta.machine(with_load=True), bench_meta.commit(SOURCE)
    print(f"# liggghts_dem  ({machine}, commit {commit})")
    for k, v in info.items():
        print(f"#   {k} = {v:.4g}" if isinstance(v, float) else f"#   {k} = {v}")
    cols = ["wall_dem_ms", "loop_us", "run_fixed_us", "set_up_us", "mesh_update_us",
            "gather_us", "broadcast_us", "protocol_io_us", "adapter_share",
            "adapter_share_total"]
    print("  ".join(["variant".ljust(14), "stat".ljust(6)] + [c.rjust(12) for c in cols]))
    for name, stats in summary.items():
        for stat in ("median", "best"):
            cells = [(f"{stats[c][stat]:.4g}" if c in stats else "-").rjust(12) for c in cols]
            print("  ".join([name.ljust(14), stat.ljust(6)] + cells))
    if a.json:
        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps({"benchmark": "liggghts_dem", "machine": machine,
                                            "commit": commit, "info": info,
                                            "summary": summary, "rows": rows}, indent=2) + "\n")
        print(f"# wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
