"""ctest check of the ParaView output of a coupled run, opened with ParaView's own XDMF reader.

Runs tests/system/paraview_output.toml with demfem_run (three processes), then
tools/inspect_output.py under pvpython (ParaView 5.11, Debian python3-paraview), and checks
what ParaView shows: every particle is a cell (a vertex), the arrays have their names and
component counts and known values, both files carry exactly the requested times (the same
doubles, so the animation has one frame per output), both series start at file 000000, and
ParaView's largest eigenvalue of the FEM strain tensor equals the solver's own
max_principal_strain in every cell, and coupling.xdmf (the interface series) carries the
same times with its node arrays.

Usage: check_paraview_output.py DEMFEM_RUN SOURCE_DIR. Exit 77 (ctest: skipped) when pvpython
is not installed (or DEMFEM_PVPYTHON names none).
"""

import json
import math
import os
import sys

from pv_checks import Checks, close, inspect_output, scene_run

check = Checks()


def opened(seen, stem, requested):
    """ParaView's view of STEM.xdmf: opened by its Xdmf3 reader at the `requested` output
    times; None (a failed check) when it was not opened."""
    x = seen.get(stem + ".xdmf")
    if not check(x is not None, f"{stem}.xdmf not opened"):
        return None
    check(x["reader"].startswith("Xdmf3Reader"), f"{stem}: reader {x['reader']}")
    check(x["times"] == requested, f"{stem}: times {x['times']}, requested {requested}")
    return x


def main():
    with scene_run("tests/system/paraview_output.toml", "--quiet") as run:
        seen = inspect_output(run.pvpython, run.source, run.out, 20)
        if seen is None:
            return 1
        files = sorted(os.listdir(run.out))
    print(json.dumps({k: {"reader": v["reader"], "times": v["times"]} for k, v in seen.items()}))

    requested = [0.0, 0.0005, 0.001, 0.0015, 0.002]
    # Both series are numbered from 0 (the initial state).
    for stem in ("particles", "walls", "fem", "coupling"):
        check(f"{stem}_000000.h5" in files and f"{stem}_000004.h5" in files and
              f"{stem}_000005.h5" not in files,
              f"{stem}: files numbered 000000 .. 000004 expected, found "
              f"{[f for f in files if f.startswith(stem + '_0')]}")

    # --- particles -------------------------------------------------------------------------
    p = opened(seen, "particles", requested)
    if p is not None:
        n = 164  # 41 x 4 x 1 spheres of 24 mm at 1.001 d spacing on the 1 m x 0.1 m beam
        mass = 7800.0 * math.pi / 6.0 * 0.024 ** 3
        expected = {"velocity": 3, "angular_velocity": 3, "radius": 1, "mass": 1,
                    "material": 1, "id": 1}
        for step in p["steps"]:
            t = step["time"]
            check(step["points"] == n, f"particles t={t}: {step['points']} points, expected {n}")
            check(step["cells"] == n,
                  f"particles t={t}: ParaView built {step['cells']} cells for {n} particles")
            # the Xdmf3 reader makes a Polyvertex cell (VTK_POLY_VERTEX) of each particle
            check(step["cell_types"] == [2], f"particles t={t}: cell types {step['cell_types']}, "
                  "expected [2] (VTK_POLY_VERTEX, one point each)")
            arrays = step["arrays"]
            for name, comps in expected.items():
                a = arrays.get(name)
                if check(a is not None, f"particles t={t}: no array '{name}'"):
                    check(a["components"] == comps and a["association"] == "point",
                          f"particles t={t}: '{name}' has {a['components']} components "
                          f"({a['association']}), expected {comps} (point)")
            if "radius" in arrays:
                check(arrays["radius"]["min"] == 0.012 and arrays["radius"]["max"] == 0.012,
                      f"particles t={t}: radius {arrays['radius']['min']}..{arrays['radius']['max']}")
            if "mass" in arrays:
                check(close(arrays["mass"]["max"], mass, 1e-12),
                      f"particles t={t}: mass {arrays['mass']['max']}, expected {mass}")
            if "id" in arrays:
                check(arrays["id"]["min"] == 0 and arrays["id"]["max"] == n - 1,
                      f"particles t={t}: ids {arrays['id']['min']}..{arrays['id']['max']}")
        if p["steps"] and "velocity" in p["steps"][0]["arrays"]:
            v0 = p["steps"][0]["arrays"]["velocity"]
            check(v0["min"] == 0.0 and v0["max"] == 0.0, "particles t=0: not at rest")

    # --- walls -----------------------------------------------------------------------------
    w = opened(seen, "walls", requested)
    if w is not None:
        for step in w["steps"]:
            t = step["time"]
            # the floor: a square of two triangles (VTK_TRIANGLE = 5), z = -0.5 m
            check(step["points"] == 4 and step["cells"] == 2 and step["cell_types"] == [5],
                  f"walls t={t}: {step['points']} points, {step['cells']} cells of types "
                  f"{step['cell_types']}, expected 4, 2, [5] (VTK_TRIANGLE)")
            force = step["arrays"].get("force")
            if check(force is not None, f"walls t={t}: no array 'force'"):
                check(force["components"] == 3 and force["association"] == "cell",
                      f"walls t={t}: 'force' has {force['components']} components "
                      f"({force['association']}), expected 3 (cell)")
                check(force["min"] == 0.0 and force["max"] == 0.0,
                      f"walls t={t}: force on the untouched floor {force['min']}..{force['max']}")

    # --- FEM -------------------------------------------------------------------------------
    f = opened(seen, "fem", requested)
    if f is not None:
        if p is not None:
            check(f["times"] == p["times"], "fem and particle times differ: ParaView's "
                  f"animation would have {len(set(f['times']) | set(p['times']))} frames")
        expected = {"displacement": (3, "point"), "velocity": (3, "point"),
                    "acceleration": (3, "point"), "reaction_force": (3, "point"),
                    "von_mises": (1, "cell"), "strain": (9, "cell"),
                    "max_principal_strain": (1, "cell")}
        for step in f["steps"]:
            t = step["time"]
            check(step["points"] == 44 and step["cells"] == 10 and step["cell_types"] == [12],
                  f"fem t={t}: {step['points']} points, {step['cells']} cells of types "
                  f"{step['cell_types']}, expected 44, 10, [12] (VTK_HEXAHEDRON)")
            arrays = step["arrays"]
            for name, (comps, where) in expected.items():
                a = arrays.get(name)
                if check(a is not None, f"fem t={t}: no array '{name}'"):
                    check(a["components"] == comps and a["association"] == where,
                          f"fem t={t}: '{name}' has {a['components']} components "
                          f"({a['association']}), expected {comps} ({where})")
        last = f["steps"][-1]["arrays"] if f["steps"] else {}
        first = f["steps"][0]["arrays"] if f["steps"] else {}
        if "displacement" in first:
            check(first["displacement"]["min"] == 0 and first["displacement"]["max"] == 0,
                  "fem t=0: the reference state is not undeformed")
        if "displacement" in last:
            check(last["displacement"]["min"] < -1e-7,
                  f"fem t=0.002: the beam did not bend under the spheres "
                  f"(displacement min {last['displacement']['min']})")
        strain, mps = last.get("strain"), last.get("max_principal_strain")
        if strain is not None and mps is not None and strain["components"] == 9:
            # ParaView's eigenvalue (Tensor Glyph) against the solver's own principal strain;
            # Tensor Glyph works in single precision: 1e-5 of the largest value.
            ours = strain.get("values", [])
            scale = max(abs(mps["min"]), abs(mps["max"]))
            pv_eig = strain.get("paraview_max_eigenvalue", [])
            check(len(pv_eig) == 10, f"fem: {len(pv_eig)} eigenvalues from ParaView, expected 10")
            for c, t9 in enumerate(ours):
                check(t9[1] == t9[3] and t9[2] == t9[6] and t9[5] == t9[7],
                      f"fem cell {c}: strain tensor not symmetric: {t9}")
            solver = mps.get("values", [])
            check(len(solver) == 10, f"fem: {len(solver)} max_principal_strain values")
            for c, (a, b) in enumerate(zip(pv_eig, solver)):
                check(abs(a - b) <= 1e-5 * scale,
                      f"fem cell {c}: ParaView's largest strain eigenvalue {a} differs from "
                      f"max_principal_strain {b}")

    # --- coupling.xdmf: the interface at the same output times ----------------------------
    c = opened(seen, "coupling", requested)
    if c is not None:
        for step in c["steps"]:
            t = step["time"]
            check(step["cell_types"] == [5] and step["cells"] > 0,
                  f"coupling t={t}: cell types {step['cell_types']}, expected [5] (VTK_TRIANGLE)")
            for name in ("force", "displacement", "position", "velocity", "dem_position"):
                a = step["arrays"].get(name)
                if check(a is not None, f"coupling t={t}: no array '{name}'"):
                    check(a["components"] == 3 and a["association"] == "point",
                          f"coupling t={t}: '{name}' has {a['components']} components "
                          f"({a['association']})")
        last = c["steps"][-1]["arrays"].get("force") if c["steps"] else None
        if last is not None:
            check(last["min"] < 0.0, f"coupling t=0.002: no downward force on the interface "
                  f"(force min {last['min']})")

    return check.report()


if __name__ == "__main__":
    sys.exit(main())
