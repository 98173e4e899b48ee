#!/usr/bin/python3
"""Writes the rig of sheet_flow_ci (docs/liggghts.md, "Grains flowing onto the sheet"): two
ASCII STL files beside this script, read by dem_server ([[dem.walls]] stl) and by the
LIGGGHTS deck (fix mesh/surface) alike. Metres; the sheet (demfem's FEM) lies in z = 0 over
x 0-0.34, y 0-0.10, clamped over x <= 0.06.

  flow_hopper.stl  a chamber 0.10 x 0.10 m (x 0.15-0.25, y 0-0.10) from z = 0.12 to 0.26,
                   its floor open over a slot 30 mm wide (x 0.185-0.215) across its width:
                   the grains stream from it onto the sheet 0.12 m below
  flow_tray.stl    an open tray around and under the sheet (x -0.10-0.45, y -0.05-0.15,
                   floor z = -0.10, walls to z = 0.10, 5 cm clear of the sheet's edges) that
                   keeps the grains running off the sheet inside LIGGGHTS's box

  ./make_flow_rig.py
"""

from pathlib import Path

HERE = Path(__file__).resolve().parent


def quad(a, b, c, d):
    """Two triangles of the planar quadrilateral a b c d."""
    return [(a, b, c), (a, c, d)]


def box_sides(x0, x1, y0, y1, z0, z1):
    return (quad((x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)) +
            quad((x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)) +
            quad((x1, y1, z0), (x0, y1, z0), (x0, y1, z1), (x1, y1, z1)) +
            quad((x0, y1, z0), (x0, y0, z0), (x0, y0, z1), (x0, y1, z1)))


def floor(x0, x1, y0, y1, z):
    return quad((x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z))


def write(name, triangles):
    lines = [f"solid {name}"]
    for t in triangles:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {p[0]!r} {p[1]!r} {p[2]!r}" for p in t]
        lines += ["    endloop", "  endfacet"]
    lines.append(f"endsolid {name}")
    (HERE / f"{name}.stl").write_text("\n".join(lines) + "\n")


def main():
    write("flow_hopper", box_sides(0.15, 0.25, 0.0, 0.1, 0.12, 0.26) +
          floor(0.15, 0.185, 0.0, 0.1, 0.12) + floor(0.215, 0.25, 0.0, 0.1, 0.12))
    write("flow_tray", box_sides(-0.1, 0.45, -0.05, 0.15, -0.1, 0.1) +
          floor(-0.1, 0.45, -0.05, 0.15, -0.1))


if __name__ == "__main__":
    main()
