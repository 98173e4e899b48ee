"""ctest check of the output of a one-way static run (issue 34, item 10), opened with ParaView.

Runs cases/beam_fixed_ci.toml (spheres settle on a clamped beam, then one static FEM solve)
with demfem_run, then tools/inspect_output.py under pvpython (ParaView 5.11, Debian
python3-paraview), and checks what ParaView shows:

* fem.xdmf holds the reference state (t = 0) and the static solution at the time the run
  says the DEM settled (the time it applies), and the displacement z of the mesh node at the
  beam check's probe point equals the mid-span deflection the run prints;
* fem_series.csv has the same two rows, the second with the static solution's largest |u|;
* coupling.xdmf opens (the interface triangles with node arrays force, displacement,
  position, velocity, dem_position) with the same times as fem.xdmf, and at the last its node
  forces sum along z to the force the run reports.

The printed numbers carry 10 significant digits (the deflection) and 9 (the force): they are
compared to 1e-8 relative; beam_check.csv's full-precision values to 1e-12 (the force) and
1e-10 (the deflection, which the beam check takes as a difference of positions).

Usage: check_static_output.py DEMFEM_RUN SOURCE_DIR. Exit 77 (ctest: skipped) without pvpython.
"""

import csv
import math
import os
import re
import sys

from pv_checks import Checks, close, inspect_output, scene_run


def main():
    check = Checks()
    with scene_run("cases/beam_fixed_ci.toml") as c:
        printed = c.run.stdout
        with open(os.path.join(c.out, "fem_series.csv")) as f:
            series = list(csv.DictReader(f))
        with open(os.path.join(c.out, "beam_check.csv")) as f:
            beam = next(csv.DictReader(f))
        seen = inspect_output(c.pvpython, c.source, c.out, 1000)
        if seen is None:
            return 1

    # What the run printed: the settle time, the force sum, the coupled deflection.
    m = re.search(r"the DEM settled at t = (\S+) s .*\(sum (\S+) N along z\)", printed)
    d = re.search(r"coupled \(DEM load\)\s+(\S+)", printed)
    if not (m and d):
        print("the run did not print the settle line and the beam check:\n" + printed)
        return 1
    t_settle, force_z, deflection = float(m.group(1)), float(m.group(2)), float(d.group(1))
    print(f"printed: settled at t = {t_settle} s, force sum {force_z} N, deflection {deflection} m")
    check(deflection < -1e-7, f"printed deflection {deflection} m: the beam did not bend")

    # --- fem.xdmf: the reference state and the static solution ---------------------------
    f = seen.get("fem.xdmf")
    if check(f is not None, "fem.xdmf not opened"):
        check(f["reader"].startswith("Xdmf3Reader"), f"fem: reader {f['reader']}")
        check(len(f["times"]) == 2 and f["times"][0] == 0.0 and
              close(f["times"][-1], t_settle, 1e-5),
              f"fem: times {f['times']}, expected [0, {t_settle}] (the reference state and the "
              "static solution at the time it applies)")
        last = f["steps"][-1]
        coords = last.get("coordinates", [])
        disp = last["arrays"].get("displacement", {}).get("values", [])
        if check(len(coords) == 189 and len(disp) == 189,
                 f"fem: {len(coords)} coordinates and {len(disp)} displacements, expected 189"):
            probe = (0.5, 0.05, 0.1)
            k = min(range(len(coords)), key=lambda i: math.dist(coords[i], probe))
            uz = disp[k][2]
            print(f"ParaView: fem.xdmf t = {f['times'][-1]}: node {k} at {coords[k]}, "
                  f"u_z = {uz!r} m")
            check(math.dist(coords[k], probe) < 1e-12, f"fem: no node at the probe {probe}")
            check(close(uz, deflection, 1e-8),
                  f"fem: ParaView's u_z {uz} at the probe differs from the printed {deflection}")
            # beam_check.csv's value is (reference z + u_z) - reference z: rounded to the
            # ulp of z = 0.1 (1.4e-17 m), 2e-11 of this deflection
            check(close(uz, float(beam["coupled"]), 1e-10),
                  f"fem: u_z {uz} differs from beam_check.csv's {beam['coupled']}")
            umax = max(math.sqrt(sum(c * c for c in u)) for u in disp)
            if check(len(series) == 2, f"fem_series.csv has {len(series)} rows, expected 2"):
                check(float(series[0]["max_displacement"]) == 0.0,
                      f"fem_series.csv t=0: max_displacement {series[0]['max_displacement']}")
                check(close(float(series[1]["time"]), t_settle, 1e-5),
                      f"fem_series.csv: time {series[1]['time']}, expected {t_settle}")
                check(close(float(series[1]["max_displacement"]), umax, 1e-12),
                      f"fem_series.csv: max_displacement {series[1]['max_displacement']}, "
                      f"ParaView's largest |u| {umax}")
        first = f["steps"][0]["arrays"].get("displacement", {})
        check(first.get("min") == 0.0 and first.get("max") == 0.0,
              "fem t=0: the reference state is not undeformed")

    # --- coupling.xdmf: the interface with its node forces -------------------------------
    c = seen.get("coupling.xdmf")
    if check(c is not None, "coupling.xdmf not opened"):
        check(c["reader"].startswith("Xdmf3Reader"), f"coupling: reader {c['reader']}")
        # the series: the reference state (t = 0, no forces) and the settled one
        check(c["times"] == f["times"] if f is not None else False,
              f"coupling: times {c['times']}, fem.xdmf's {f['times'] if f else None}")
        check(len(c["times"]) == 2 and c["times"][0] == 0.0 and
              close(c["times"][-1], t_settle, 1e-5),
              f"coupling: times {c['times']}, expected [0, {t_settle}]")
        first = c["steps"][0]["arrays"].get("force", {})
        check(first.get("min") == 0.0 and first.get("max") == 0.0,
              "coupling t=0: forces on the interface before the first step")
        step = c["steps"][-1]
        # the top face z = 0.1: 21 x 3 nodes, 20 x 2 quads as 80 triangles (VTK_TRIANGLE = 5)
        check(step["points"] == 63 and step["cells"] == 80 and step["cell_types"] == [5],
              f"coupling: {step['points']} points, {step['cells']} cells of types "
              f"{step['cell_types']}, expected 63, 80, [5]")
        arrays = step["arrays"]
        for name in ("force", "displacement", "position", "velocity", "dem_position"):
            a = arrays.get(name)
            if check(a is not None, f"coupling: no array '{name}'"):
                check(a["components"] == 3 and a["association"] == "point",
                      f"coupling: '{name}' has {a['components']} components ({a['association']})")
        forces = arrays.get("force", {}).get("values", [])
        if check(len(forces) == 63, f"coupling: {len(forces)} force values, expected 63"):
            fz = sum(v[2] for v in forces)
            print(f"ParaView: coupling.xdmf forces sum to {fz!r} N along z")
            check(close(fz, force_z, 1e-8),
                  f"coupling: ParaView's forces sum to {fz} N, the run reported {force_z} N")
            check(close(-fz, float(beam["coupled_load"]), 1e-12),
                  f"coupling: forces sum to {fz} N, beam_check.csv's load {beam['coupled_load']}")
        disp = arrays.get("displacement", {}).get("values", [])
        coords = step.get("coordinates", [])
        if len(disp) == 63 and len(coords) == 63:
            k = min(range(63), key=lambda i: math.dist(coords[i], (0.5, 0.05, 0.1)))
            check(close(disp[k][2], deflection, 1e-8),
                  f"coupling: displacement {disp[k][2]} at the probe, printed {deflection}")

    return check.report()


if __name__ == "__main__":
    sys.exit(main())
