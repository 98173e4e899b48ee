"""What ParaView sees of a run's output: opens particles.xdmf, walls.xdmf, fem.xdmf,
fem_modes.xdmf (a modal analysis: one time step per mode) and coupling.xdmf (the coupling
interface) of an output folder with ParaView's own default reader (Xdmf3ReaderS in 5.11) and
prints, as JSON, for every file and time step: the reader, the time values, the point and cell counts, the cell
types, and each array (point or cell data: components, range, first tuple). For arrays of 9
(or 6) components it also gives ParaView's largest eigenvalue of each cell's tensor, computed
by ParaView's Tensor Glyph filter (which reads 6 components as the symmetric tensor XX, YY,
ZZ, XY, YZ, XZ and 9 as a full tensor), so that a test can compare it with an independent
value.

Run it with ParaView's Python (Debian: python3-paraview), no display needed:

    pvpython tools/inspect_output.py OUTPUT_DIR [--steps all|first-last] [--values N] > seen.json
"""

import argparse
import json
import os
import sys

from demfem_post.needs import need_or_exit

# ParaView's Python: pvpython (Debian: python3-paraview), no display needed
PARAVIEW = ("python3-paraview", "pvpython")
sm = need_or_exit("inspect_output.py", "paraview.servermanager", *PARAVIEW)
pv = need_or_exit("inspect_output.py", "paraview.simple", *PARAVIEW)
vtk_to_numpy = need_or_exit("inspect_output.py", "vtkmodules.util.numpy_support",
                            *PARAVIEW).vtk_to_numpy


def unstructured_blocks(data):
    """The unstructured grids of a reader output (a composite for spatial collections)."""
    if data is None:
        return []
    if data.IsA("vtkCompositeDataSet"):
        blocks = []
        it = data.NewIterator()
        it.InitTraversal()
        while not it.IsDoneWithTraversal():
            blocks.append(it.GetCurrentDataObject())
            it.GoToNextItem()
        return blocks
    return [data]


def largest_eigenvalues(reader, time, name):
    """ParaView's largest eigenvalue of the cell tensor array `name`, one per cell: Cell
    Centers carries the tensor to points, Tensor Glyph (scale factor 1, coloured by
    eigenvalues) writes it as MaxEigenvalue on every point of that point's glyph."""
    centres = pv.CellCenters(Input=reader)
    glyph = pv.TensorGlyph(Input=centres, GlyphType="Sphere")
    glyph.Tensors = ["POINTS", name]
    glyph.ScaleFactor = 1.0
    glyph.ColorGlyphs = 1
    glyph.Colorby = "eigenvalues"
    glyph.UpdatePipeline(time)
    centres.UpdatePipeline(time)
    values = []
    for c, g in zip(unstructured_blocks(sm.Fetch(centres)), unstructured_blocks(sm.Fetch(glyph))):
        n = c.GetNumberOfPoints()
        arr = g.GetPointData().GetArray("MaxEigenvalue")
        if n == 0 or arr is None:
            continue
        v = vtk_to_numpy(arr)
        per_glyph = len(v) // n  # every glyph has the sphere's point count
        values.extend(float(x) for x in v[::per_glyph])
    pv.Delete(glyph)
    pv.Delete(centres)
    return values


def describe_step(reader, time, max_values):
    reader.UpdatePipeline(time)
    data = sm.Fetch(reader)
    step = {"time": time, "points": 0, "cells": 0, "cell_types": [], "arrays": {}}
    types = set()
    for block in unstructured_blocks(data):
        if 0 < block.GetNumberOfPoints() <= max_values:
            # the point coordinates as ParaView placed them (after the values of its arrays)
            step.setdefault("coordinates", []).extend(
                [float(x) for x in row] for row in vtk_to_numpy(block.GetPoints().GetData()))
        step["points"] += block.GetNumberOfPoints()
        step["cells"] += block.GetNumberOfCells()
        for c in range(block.GetNumberOfCells()):
            types.add(block.GetCellType(c))
        for where, fields in (("point", block.GetPointData()), ("cell", block.GetCellData())):
            for i in range(fields.GetNumberOfArrays()):
                arr = fields.GetArray(i)
                if arr is None:
                    continue
                values = vtk_to_numpy(arr)
                ncomp = arr.GetNumberOfComponents()
                entry = step["arrays"].setdefault(
                    arr.GetName(),
                    {"association": where, "components": ncomp, "tuples": 0,
                     "min": None, "max": None, "first": None})
                entry["tuples"] += arr.GetNumberOfTuples()
                if arr.GetNumberOfTuples() > 0:
                    flat = values.reshape(-1)
                    lo, hi = float(flat.min()), float(flat.max())
                    entry["min"] = lo if entry["min"] is None else min(entry["min"], lo)
                    entry["max"] = hi if entry["max"] is None else max(entry["max"], hi)
                    if entry["first"] is None:
                        first = values[0]
                        entry["first"] = [float(x) for x in (first if ncomp > 1 else [first])]
                    if arr.GetNumberOfTuples() <= max_values:
                        rows = values.reshape(arr.GetNumberOfTuples(), ncomp)
                        entry.setdefault("values", []).extend(
                            [float(x) for x in row] if ncomp > 1 else float(row[0])
                            for row in rows)
    step["cell_types"] = sorted(types)
    for name, entry in step["arrays"].items():
        if entry["association"] == "cell" and entry["components"] in (6, 9):
            entry["paraview_max_eigenvalue"] = largest_eigenvalues(reader, time, name)
    return step


def describe_file(path, steps, max_values):
    reader = pv.OpenDataFile(path)
    if reader is None:
        return {"file": path, "error": "ParaView found no reader"}
    values = reader.TimestepValues
    if isinstance(values, (int, float)):  # one time step: ParaView gives the number itself
        values = [values]
    times = [float(t) for t in values] if values else [0.0]
    chosen = times if steps == "all" else sorted(set([times[0], times[-1]]))
    out = {"file": os.path.basename(path), "reader": reader.GetXMLName(), "times": times,
           "steps": [describe_step(reader, t, max_values) for t in chosen]}
    pv.Delete(reader)
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("output_dir")
    parser.add_argument("--steps", choices=["all", "first-last"], default="first-last")
    parser.add_argument("--values", type=int, default=0, metavar="N",
                        help="also list every value of the arrays of at most N tuples (and the "
                             "point coordinates of blocks of at most N points)")
    args = parser.parse_args()
    seen = {}
    for name in ("particles.xdmf", "walls.xdmf", "fem.xdmf", "fem_modes.xdmf", "coupling.xdmf"):
        path = os.path.join(args.output_dir, name)
        if os.path.exists(path):
            seen[name] = describe_file(path, args.steps, args.values)
    if not seen:
        print(f"{args.output_dir}: none of particles.xdmf, walls.xdmf, fem.xdmf, fem_modes.xdmf, "
              "coupling.xdmf found",
              file=sys.stderr)
        return 2
    json.dump(seen, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
