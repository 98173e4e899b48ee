#!/usr/bin/env pvpython
"""The bed in the sheet rig's upper chamber at each particle snapshot of a run: the grain left
above the slides and the height of its free surface along the chamber.

usage: pvpython tools/sheet_bed_profile.py OUTPUT_DIR [--slides 0.365] [--x0 -0.10] [--x1 0.50]
                                           [--bins 12] [--density 1242]

Reads OUTPUT_DIR/particles.xdmf (ParaView's XDMF reader, as tools/inspect_output.py). For each
snapshot prints the time, the number and mass of the grains whose centre lies above the
slides (z > --slides), and the free surface over --bins equal bins of x in [--x0, --x1]: the
98th percentile of the centres' heights in the bin, above the slides (m; "-" for a bin with
fewer than 6 grains). The surface's slope beside the outlet gives the angle of the wedges left.
"""
import argparse
import os
import sys

from demfem_post.needs import need_or_exit

# ParaView's Python: pvpython (Debian: python3-paraview), no display needed
PARAVIEW = ("python3-paraview", "pvpython")
np = need_or_exit("sheet_bed_profile.py", "numpy", *PARAVIEW)
sm = need_or_exit("sheet_bed_profile.py", "paraview.servermanager", *PARAVIEW)
pv = need_or_exit("sheet_bed_profile.py", "paraview.simple", *PARAVIEW)
vtk_to_numpy = need_or_exit("sheet_bed_profile.py", "vtkmodules.util.numpy_support",
                            *PARAVIEW).vtk_to_numpy


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("output_dir")
    p.add_argument("--slides", type=float, default=0.365)
    p.add_argument("--x0", type=float, default=-0.10)
    p.add_argument("--x1", type=float, default=0.50)
    p.add_argument("--bins", type=int, default=12)
    p.add_argument("--density", type=float, default=1242.0)
    a = p.parse_args()
    path = os.path.abspath(os.path.join(a.output_dir, "particles.xdmf"))
    if not os.path.isfile(path):
        print(f"sheet_bed_profile.py: {path}: no such file", file=sys.stderr)
        return 2
    reader = pv.Xdmf3ReaderS(FileName=[path])
    edges = np.linspace(a.x0, a.x1, a.bins + 1)
    print("time_s grains mass_kg surface_m_per_bin(x " +
          " ".join(f"{0.5 * (l + h):.3f}" for l, h in zip(edges[:-1], edges[1:])) + ")")
    for t in reader.TimestepValues:
        reader.UpdatePipeline(t)
        data = sm.Fetch(reader)
        if data.IsA("vtkMultiBlockDataSet"):
            data = data.GetBlock(0)
        pos = vtk_to_numpy(data.GetPoints().GetData())
        radius = vtk_to_numpy(data.GetPointData().GetArray("radius"))
        above = pos[:, 2] > a.slides
        mass = (a.density * 4.0 / 3.0 * np.pi * radius[above] ** 3).sum()
        x, z = pos[above, 0], pos[above, 2]
        cells = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            sel = (x >= lo) & (x < hi)
            cells.append(f"{np.percentile(z[sel], 98) - a.slides:.3f}" if sel.sum() > 5 else "-")
        print(f"{t:.2f} {above.sum()} {mass:.3f} " + " ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
