"""ctest check (issue 34, item 11): rocks and walls as a ParaView user gets them.

Runs tests/system/paraview_rocks.toml (20 rocks and 10 spheres in a box, a second wall named
"lid plate") with demfem_run, then tests/system/paraview_rocks_probe.py under pvpython
(ParaView 5.11's default reader, Xdmf3ReaderS, which merges a snapshot's spheres and rock
surfaces into unnamed pieces of one data set) and checks:
  * every piece of particles.xdmf carries id, material, radius, mass, velocity and
    angular_velocity as point AND cell arrays (a field missing on a piece leaves that piece
    plain white when the user colours by it);
  * each rock's triangles carry that rock's values: the cell values of each id on the rock
    surfaces equal the sphere piece's values of the same particle (its points are the
    particles' centres), and its surface points carry them too;
  * each wall has its own index walls_<name>.xdmf that opens as one data set (not pieces) with
    the wall's triangles, so it can be shown, hidden and coloured by name; walls.xdmf has the
    `wall` cell field (the wall's index) on every piece.

Usage: check_paraview_rocks.py DEMFEM_RUN SOURCE_DIR. Exit 77 (ctest: skipped) without pvpython.
"""

import os
import sys

from pv_checks import Checks, pvpython_json, scene_run

check = Checks()


FIELDS = {"id": 1, "material": 1, "radius": 1, "mass": 1, "velocity": 3, "angular_velocity": 3}


def main():
    with scene_run("tests/system/paraview_rocks.toml", "--quiet") as c:
        probe = os.path.join(c.source, "tests", "system", "paraview_rocks_probe.py")
        seen = pvpython_json(c.pvpython, probe, c.out)
        if seen is None:
            return 1

    # --- rocks and spheres -------------------------------------------------------------------
    p = seen.get("particles.xdmf")
    if check(p is not None, "particles.xdmf not opened"):
        check(p["reader"] == "Xdmf3ReaderS", f"particles: reader {p['reader']}")
        for name in FIELDS:
            check(name in p["point_arrays"] and name in p["cell_arrays"],
                  f"particles: '{name}' not both a point and a cell array of the reader "
                  f"(points {p['point_arrays']}, cells {p['cell_arrays']})")
        pieces = p["leaves"]
        check(len(pieces) == 2, f"particles: {len(pieces)} pieces, expected 2 (spheres, rocks)")
        for k, piece in enumerate(pieces):
            for where in ("point", "cell"):
                for name, comps in FIELDS.items():
                    a = piece[where].get(name)
                    if check(a is not None, f"particles piece {k}: no {where} array '{name}'"):
                        n = piece["points"] if where == "point" else piece["cells"]
                        check(len(a) == n, f"particles piece {k}: {where} '{name}' has {len(a)} "
                              f"values for {n} {where}s")
                        if comps > 1:
                            check(all(len(v) == comps for v in a),
                                  f"particles piece {k}: {where} '{name}' not {comps} components")
        if len(pieces) == 2:
            centres = next((q for q in pieces if q["points"] == q["cells"]), None)
            rocks = next((q for q in pieces if q is not centres), None)
            if check(centres is not None and rocks is not None,
                     "particles: no piece of one cell per point (the particles' centres)"):
                check(centres["points"] == 30, f"particles: {centres['points']} centres, expected 30")
                by_id = {}
                for i, pid in enumerate(centres["point"].get("id", [])):
                    by_id[pid] = {n: centres["point"][n][i] for n in FIELDS if n in centres["point"]}
                    for n in FIELDS:
                        if n in centres["cell"]:
                            check(centres["cell"][n][i] == centres["point"][n][i],
                                  f"particle {pid}: cell '{n}' differs from its point value")
                rock_ids = sorted(set(rocks["cell"].get("id", [])))
                check(len(rock_ids) == 20, f"rock surfaces: {len(rock_ids)} rocks, expected 20")
                for where in ("cell", "point"):
                    arr = rocks[where]
                    for i, pid in enumerate(arr.get("id", [])):
                        ref = by_id.get(pid)
                        if not check(ref is not None, f"rock {where} {i}: id {pid} is no particle"):
                            break
                        for n in ("material", "radius", "mass", "angular_velocity"):
                            if n in arr and not check(arr[n][i] == ref[n],
                                                      f"rock {pid} {where} {i}: '{n}' {arr[n][i]} "
                                                      f"but the particle's is {ref[n]}"):
                                break
                    if where == "cell" and "velocity" in arr:
                        for i, pid in enumerate(arr.get("id", [])):
                            if pid in by_id and arr["velocity"][i] != by_id[pid]["velocity"]:
                                check(False, f"rock {pid} cell {i}: velocity is not the centre's")
                                break
                radii = set(by_id[i]["radius"] for i in rock_ids if i in by_id)
                check(len(radii) > 1, "rock surfaces: every rock has the same radius (no test)")

    # --- walls -------------------------------------------------------------------------------
    w = seen.get("walls.xdmf")
    if check(w is not None, "walls.xdmf not opened"):
        check(all(n in w["cell_arrays"] for n in ("wall", "force", "sensor_force")),
              f"walls.xdmf: cell arrays {w['cell_arrays']}")
        indexes = sorted(set(v for q in w["leaves"] for v in q["cell"].get("wall", [])))
        check(indexes == [0, 1], f"walls.xdmf: wall indexes {indexes}, expected [0, 1]")
    for name, index, cells in (("walls_box.xdmf", 0, 10), ("walls_lid_plate.xdmf", 1, 2)):
        x = seen.get(name)
        if check(x is not None, f"{name} (the wall's own index) not found"):
            check(x["class"] == "vtkUnstructuredGrid",
                  f"{name}: a {x['class']}, expected one data set (vtkUnstructuredGrid)")
            check(len(x["times"]) == 3, f"{name}: times {x['times']}")
            q = x["leaves"][0] if x["leaves"] else {"cells": 0, "cell": {}}
            check(q["cells"] == cells, f"{name}: {q['cells']} triangles, expected {cells}")
            check(q["cell"].get("wall") == [index] * cells,
                  f"{name}: 'wall' {q['cell'].get('wall')}, expected {index} on each triangle")
    check(sorted(k for k in seen if k.startswith("walls")) ==
          ["walls.xdmf", "walls_box.xdmf", "walls_lid_plate.xdmf"],
          f"wall indexes found: {sorted(k for k in seen if k.startswith('walls'))}")

    return check.report()


if __name__ == "__main__":
    sys.exit(main())
