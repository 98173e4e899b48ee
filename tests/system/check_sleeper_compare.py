"""ctest check of tools/sleeper_compare.py on two made-up sleeper run folders whose series are
linear in time, so that every figure is known in closed form (the references below are written
from the formulas, not taken from the tool):

  probes b1_uz = -0.01 - 0.05 t, b2_uz = -0.01 - 0.03 t (m): settlement 1e3 (-0.01 - 0.04 t) mm;
  the second run 2 mm lower from t = 0.2 s on, and ending at 0.35 s
  force_z = 1000 + 2e5 t (N); the strain gauge sg_centre_0/_1 (probes 1 mm inside the mesh nodes
  at x 1.5 and 1.7 m of the first run's scene, named by its run.json; the second has none) ux_1 - ux_0 = 2e-5 t; base fz = -(40000 + 1e5 t) (N)
  cell1: vertical pressure 1e5 (1 + t) Pa on a face of 0.0484 m^2, its force 1 % tilted off the
         vertical (so the pressure is -fz / area, not the force's magnitude over it)
  packing_upper: Z = 4 + t, solid fraction 0.6, every 0.01 s; kinetic energy t J every 0.01 s;
  fem_series max_principal_strain 1e-4 t every 0.02 s.

A window mean of a linear series over samples placed symmetrically about the moment is its
value there (tolerance 1e-9 relative). Also: the difference column, the settlement curves'
largest difference (2 mm, to the second run's end), --json, a moment after a run's end refused
with exit 2 naming that run, and a malformed --at refused."""

import json
import math
import os
import subprocess
import sys
import tempfile

script = sys.argv[1]
AREA = 0.0484
fail = []


def write(path, header, rows):
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(x)) for x in r) + "\n")


def make_run(d, shift_mm, end, scene=None):
    os.makedirs(d)
    if scene:  # the run's record naming its scene, where the strain gauges' probes stand
        with open(os.path.join(d, "run.json"), "w") as f:
            json.dump({"status": "completed", "scene": scene, "overrides": []}, f)
    n = round(end / 0.001)
    times = [0.001 * i for i in range(n + 1)]
    def uz(t, a):
        return -0.01 - a * t - (shift_mm * 1e-3 if t >= 0.2 - 1e-12 else 0.0)
    write(os.path.join(d, "fem_monitor.csv"),
          ["time", "b1_ux", "b1_uz", "b2_uz", "sg_centre_0_ux", "sg_centre_1_ux", "force_z"],
          [(t, 0.0, uz(t, 0.05), uz(t, 0.03), 0.0, 2e-5 * t, 1000 + 2e5 * t) for t in times])
    write(os.path.join(d, "sensor_base.csv"), ["time", "fx", "fy", "fz", "force", "pressure"],
          [(t, 0, 0, -(40000 + 1e5 * t), 40000 + 1e5 * t, (40000 + 1e5 * t) / 10.24)
           for t in times])
    rows = []
    for t in times:
        fz = -1e5 * (1 + t) * AREA
        fx = 0.01 * fz
        force = math.hypot(fx, fz)
        rows.append((t, fx, 0, fz, force, force / AREA))
    write(os.path.join(d, "sensor_cell1.csv"), ["time", "fx", "fy", "fz", "force", "pressure"],
          rows)
    coarse = [0.01 * i for i in range(round(end / 0.01) + 1)]
    write(os.path.join(d, "sensor_packing_upper.csv"),
          ["time", "particles", "solid_fraction", "coordination", "top"],
          [(t, 100, 0.6, 4 + t, 0.8) for t in coarse])
    write(os.path.join(d, "sensor_kinetic_energy.csv"), ["time", "kinetic_energy"],
          [(t, t) for t in coarse])
    write(os.path.join(d, "fem_series.csv"), ["time", "max_principal_strain"],
          [(0.02 * i, 1e-4 * 0.02 * i) for i in range(round(end / 0.02) + 1)])


def close(name, got, want, tol=1e-9):
    if not math.isclose(got, want, rel_tol=tol, abs_tol=1e-12):
        fail.append(f"{name}: {got!r}, expected {want!r}")


with tempfile.TemporaryDirectory() as tmp:
    a, b = os.path.join(tmp, "a"), os.path.join(tmp, "b")
    scene = os.path.join(tmp, "scene.toml")
    with open(scene, "w") as f:  # the probes 1 mm off the nodes: the gauge is the nodes' 0.2 m
        f.write('[fem.mesh]\nfile = "mesh.inp"\n'
                '[[fem.monitor.probes]]\nname = "sg_centre_0"\npoint = [1.501, 0.5, 0.8]\n'
                '[[fem.monitor.probes]]\nname = "sg_centre_1"\npoint = [1.699, 0.5, 0.8]\n')
    with open(os.path.join(tmp, "mesh.inp"), "w") as f:
        f.write("*NODE\n1, 1.3, 0.5, 0.8\n2, 1.5, 0.5, 0.8\n3, 1.7, 0.5, 0.8\n4, 1.9, 0.5, 0.8\n")
    make_run(a, 0.0, 0.4, scene)
    make_run(b, 2.0, 0.35)
    js = os.path.join(tmp, "cmp.json")
    r = subprocess.run([sys.executable, script, a, b, "--at", "0.26,0.3", "--window", "0.006",
                        "--from", "0.22", "--json", js], capture_output=True, text=True)
    if r.returncode != 0:
        print("the comparison failed:", r.returncode, r.stdout, r.stderr)
        sys.exit(1)
    print(r.stdout)
    with open(js) as f:
        out = json.load(f)
    for m in out["moments"]:
        t = m["time"]
        fa, fb = m["figures"][a], m["figures"][b]
        close(f"settlement at {t}", fa["settlement_mm"], 1e3 * (-0.01 - 0.04 * t))
        close(f"second run's settlement at {t}", fb["settlement_mm"],
              1e3 * (-0.01 - 0.04 * t) - 2.0)
        close(f"under the load at {t}", fa["under_load_mm"], -40.0 * (t - 0.22))
        close(f"interface force at {t}", fa["interface_fz_kN"], (1000 + 2e5 * t) / 1e3)
        # gauge 0.2 m long, u1 - u0 = 2e-5 t: strain 1e-4 t = 100 t microstrain
        close(f"centre gauge at {t}", fa.get("strain_centre_ue", math.nan), 100 * t)
        if "strain_centre_ue" in fb:
            fail.append("the run without run.json shows a gauge strain")
        close(f"base at {t}", fa["base_kN"], 40 + 100 * t)
        close(f"cell1 at {t}", fa["cell1_kPa"], 100 * (1 + t))
        close(f"Z at {t}", fa["packing_upper_Z"], 4 + t)
        close(f"solid fraction at {t}", fa["packing_upper_phi"], 0.6)
        close(f"kinetic energy at {t}", fa["kinetic_energy_J"], t)
        # fem_series every 0.02 s: the sample nearest t
        close(f"strain at {t}", fa["max_principal_strain_ue"], 100 * round(t / 0.02) * 0.02)
    curve = out["settlement_curve"][0]
    close("settlement curves' largest difference", curve["largest_difference_mm"], 2.0)
    close("settlement curves compared up to", curve["until_s"], 0.35)
    row = next((ln.split() for ln in r.stdout.splitlines() if ln.startswith("settlement_mm")), [])
    if row[-1:] != ["-2"]:
        fail.append(f"the difference column of the settlement shows {row[-1:]}, not -2 (mm)")

    r = subprocess.run([sys.executable, script, a, b, "--at", "0.38"], capture_output=True,
                       text=True)
    if r.returncode != 2 or b not in r.stderr or "0.35" not in r.stderr:
        fail.append(f"a moment after the second run's end: exit {r.returncode}, {r.stderr!r}")
    r = subprocess.run([sys.executable, script, a, b, "--at", "0.2;0.3"], capture_output=True,
                       text=True)
    if r.returncode != 2 or "--at" not in r.stderr:
        fail.append(f"a malformed --at: exit {r.returncode}, {r.stderr!r}")

if fail:
    print("FAILED:\n  " + "\n  ".join(fail))
    sys.exit(1)
print("sleeper_compare.py: every figure as its formula")
