#!/usr/bin/env python3
"""Writes funnel.stl: a square funnel (pyramid frustum + vertical reservoir), ASCII STL, m.

Outlet: a square of half-width B at height Z0; the sloped walls rise at ANGLE degrees from the
horizontal to half-width A; vertical walls continue up to Z_TOP. Normals point to the funnel
axis (the particle side). Used by cases/heap_repose.toml.
"""
import math
import sys

B, A, Z0, ANGLE, Z_TOP = 0.02, 0.06, 0.035, 60.0, 0.33
Z1 = Z0 + (A - B) * math.tan(math.radians(ANGLE))


def ring(h, z):
    return [(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)]


def facets():
    rings = [ring(B, Z0), ring(A, Z1), ring(A, Z_TOP)]
    for lo, hi in zip(rings, rings[1:]):
        for k in range(4):
            a, b, c, d = lo[k], lo[(k + 1) % 4], hi[(k + 1) % 4], hi[k]
            for tri in ((a, b, c), (a, c, d)):
                yield orient(tri)


def orient(tri):
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = tri
    u = (bx - ax, by - ay, bz - az)
    v = (cx - ax, cy - ay, cz - az)
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    # Towards the axis: the normal's horizontal part must point at -(centroid's horizontal part).
    mx, my = (ax + bx + cx) / 3, (ay + by + cy) / 3
    if n[0] * mx + n[1] * my > 0:
        tri = (tri[0], tri[2], tri[1])
        n = (-n[0], -n[1], -n[2])
    length = math.sqrt(sum(x * x for x in n))
    return tri, tuple(x / length for x in n)


def main(path):
    with open(path, "w") as out:
        out.write("solid funnel\n")
        for tri, n in facets():
            out.write("  facet normal %.9g %.9g %.9g\n    outer loop\n" % n)
            for p in tri:
                out.write("      vertex %.9g %.9g %.9g\n" % p)
            out.write("    endloop\n  endfacet\n")
        out.write("endsolid funnel\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "funnel.stl")
