#!/usr/bin/env python3
"""Writes the timber sleeper of the ballast case (thesis ch. 6, table 6.1) as an Abaqus deck of
C3D8I hexahedra: 2.5 x 0.2 x 0.18 m (L x W x H), long axis along x, centred on the bed at
x = 1.6 m, y = 0.5 m.

The x divisions put nodes on the edges of the two rail seats (0.15 x 0.2 m centred at
x = 0.8825 and 2.3175 m, table 6.1), so a face selector such as
    "z >= <top> and x >= 0.8075 and x <= 0.9575"
takes exactly the rail-seat patch (pressure = force / 0.03 m^2). Default: 50 x 4 x 4 = 800
elements (dx about 0.05 m, 0.05 m across, 0.045 m through the height); --refine k
multiplies every count by k (k = 2: 6400 elements).

The deck holds nodes, elements (element set SLEEPER), node sets BOTTOM and TOP and element
surfaces RAIL_1, RAIL_2 (top faces of the seats) and BOTTOM_FACE (the whole bottom): the
scene gives material and section ([[fem.materials]], [[fem.sections]]), loads and the
coupled surface (the whole exterior by default).

    /usr/bin/python3 cases/geometry/make_sleeper.py [--refine K] [--z0 Z] [--y0 Y] [--out F]

--z0 is the height of the sleeper's bottom (default 0.805 m: 5 mm above the 0.8 m bed);
--y0 the lower y edge (default 0.4: centred on the 1 m wide bed). A slice bed (the CI case)
passes its own values.
"""
import argparse
import sys

LENGTH, WIDTH, HEIGHT = 2.5, 0.2, 0.18   # table 6.1
BED_CENTRE_X = 1.6                       # the middle of the 3.2 m box (thesis 6.2)
RAILS = (0.8825, 2.3175)                 # rail positions (table 6.1)
RAIL_LEN = 0.15                          # rail seat along the sleeper (table 6.1: 0.15 x 0.2)


def divisions(a, b, h):
    n = max(1, round((b - a) / h))
    return [a + (b - a) * k / n for k in range(n)]


def x_nodes(refine):
    x0 = BED_CENTRE_X - LENGTH / 2
    marks = [x0]
    for c in RAILS:
        marks += [c - RAIL_LEN / 2, c + RAIL_LEN / 2]
    marks.append(x0 + LENGTH)
    xs = []
    h = 0.05 / refine
    for a, b in zip(marks[:-1], marks[1:]):
        xs += divisions(a, b, h)
    xs.append(marks[-1])
    return xs


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--refine", type=int, default=1, help="multiply the element counts (>= 1)")
    ap.add_argument("--z0", type=float, default=0.805, help="height of the bottom face, m")
    ap.add_argument("--y0", type=float, default=0.4, help="lower y edge, m")
    ap.add_argument("--out", default=None, help="output .inp (default: next to this script)")
    a = ap.parse_args(argv)
    if a.refine < 1 or a.refine > 16:
        ap.error("--refine must be in [1, 16]")
    xs = x_nodes(a.refine)
    ny, nz = 4 * a.refine, 4 * a.refine
    ys = [a.y0 + WIDTH * j / ny for j in range(ny + 1)]
    zs = [a.z0 + HEIGHT * k / nz for k in range(nz + 1)]
    nx = len(xs) - 1

    def nid(i, j, k):
        return 1 + i + (nx + 1) * (j + (ny + 1) * k)

    def eid(i, j, k):
        return 1 + i + nx * (j + ny * k)

    out = a.out or __file__.rsplit("/", 1)[0] + (
        "/sleeper.inp" if a.refine == 1 else f"/sleeper_r{a.refine}.inp")
    lines = ["*HEADING", f"timber sleeper {LENGTH} x {WIDTH} x {HEIGHT} m, {nx * ny * nz} C3D8I "
             f"(make_sleeper.py --refine {a.refine} --z0 {a.z0} --y0 {a.y0})", "*NODE"]
    for k, z in enumerate(zs):
        for j, y in enumerate(ys):
            for i, x in enumerate(xs):
                lines.append(f"{nid(i, j, k)}, {x:.10g}, {y:.10g}, {z:.10g}")
    lines.append("*ELEMENT, TYPE=C3D8I, ELSET=SLEEPER")
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                n = [nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                     nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1),
                     nid(i, j + 1, k + 1)]
                lines.append(f"{eid(i, j, k)}, " + ", ".join(map(str, n)))

    def nset(name, ids):
        lines.append(f"*NSET, NSET={name}")
        for s in range(0, len(ids), 16):
            lines.append(", ".join(map(str, ids[s:s + 16])))

    nset("BOTTOM", [nid(i, j, 0) for j in range(ny + 1) for i in range(nx + 1)])
    nset("TOP", [nid(i, j, nz) for j in range(ny + 1) for i in range(nx + 1)])

    def surface(name, elems, face):
        lines.append(f"*SURFACE, NAME={name}, TYPE=ELEMENT")
        lines.extend(f"{e}, {face}" for e in elems)

    for r, c in enumerate(RAILS, 1):
        lo, hi = c - RAIL_LEN / 2 - 1e-9, c + RAIL_LEN / 2 + 1e-9
        elems = [eid(i, j, nz - 1) for j in range(ny) for i in range(nx)
                 if xs[i] >= lo and xs[i + 1] <= hi]
        surface(f"RAIL_{r}", elems, "S2")  # S2: the face of nodes 5-8 (top)
    surface("BOTTOM_FACE", [eid(i, j, 0) for j in range(ny) for i in range(nx)], "S1")
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"{out}: {nx} x {ny} x {nz} = {nx * ny * nz} elements, {len(xs) * (ny + 1) * (nz + 1)} "
          f"nodes; rail seats x = {RAILS[0] - RAIL_LEN / 2:.4f}-{RAILS[0] + RAIL_LEN / 2:.4f}, "
          f"{RAILS[1] - RAIL_LEN / 2:.4f}-{RAILS[1] + RAIL_LEN / 2:.4f}; bottom z = {a.z0}")


if __name__ == "__main__":
    main(sys.argv[1:])
