"""pvpython side of check_paraview_rocks.py: opens particles.xdmf and every walls*.xdmf of an
output folder with ParaView's default reader (OpenDataFile, as the GUI does) at the last
time and prints, as JSON, what ParaView holds: per file the reader, the data set's class, the
reader's point and cell array names, and per leaf data set (a piece of the merged
collection) its points, cells and every array's values.

Usage: pvpython paraview_rocks_probe.py OUTPUT_DIR
"""
import glob
import json
import os
import sys

from paraview.simple import OpenDataFile
import paraview.servermanager as sm
from vtkmodules.numpy_interface import dataset_adapter as dsa


def leaves(data):
    if data is None:
        return []
    if data.IsA("vtkCompositeDataSet"):
        it = data.NewIterator()
        it.InitTraversal()
        out = []
        while not it.IsDoneWithTraversal():
            out.append(it.GetCurrentDataObject())
            it.GoToNextItem()
        return out
    return [data]


def arrays(fields):
    out = {}
    for i in range(fields.GetNumberOfArrays()):
        a = fields.GetArray(i)
        values = [list(a.GetTuple(k)) if a.GetNumberOfComponents() > 1 else a.GetTuple(k)[0]
                  for k in range(a.GetNumberOfTuples())]
        out[a.GetName()] = values
    return out


def main():
    out = sys.argv[1]
    seen = {}
    files = [os.path.join(out, "particles.xdmf")] + sorted(glob.glob(os.path.join(out, "walls*.xdmf")))
    for path in files:
        r = OpenDataFile(path)
        times = list(r.TimestepValues) if r.TimestepValues else [0.0]
        r.UpdatePipeline(times[-1])
        data = sm.Fetch(r)
        seen[os.path.basename(path)] = {
            "reader": r.GetXMLName(),
            "class": data.GetClassName(),
            "times": times,
            "point_arrays": list(r.PointData.keys()),
            "cell_arrays": list(r.CellData.keys()),
            "leaves": [{"points": b.GetNumberOfPoints(), "cells": b.GetNumberOfCells(),
                        "point": arrays(b.GetPointData()), "cell": arrays(b.GetCellData())}
                       for b in leaves(data)],
        }
    print(json.dumps(seen))


main()
