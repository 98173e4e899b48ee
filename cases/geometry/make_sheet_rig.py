#!/usr/bin/env python3
"""Writes the rigid walls of the steel-sheet rig (thesis ch. 5, Dratt & Katterfeld 2017) as
ASCII STL files (metres) next to this script:

  sheet_chamber.stl     upper chamber: four side walls (0.30 x 0.10 m inside), the front and
                        back walls reach down past the flaps (the flap housing)
  sheet_slides.stl      the two hand slides (a 40 mm outlet between them) and the two walls
                        that close the 12 mm pocket between slides and flaps at its ends
  sheet_flap_left.stl   the flaps beneath the outlet, closed (the scenes rotate them open:
  sheet_flap_right.stl  90 degrees about their outer edges in 0.2 s)
  sheet_frame.stl       the clamp of the sheet: upper and lower jaw over 60 x 100 mm, a post
  sheet_bin.stl         the lower chamber that catches the grain (open at the top)

Every part is a closed box surface (12 triangles; contacts are two-sided, so a thin box is a
plate of that thickness), the bin a box without its top. The sheet itself is the FEM mesh:
mid-surface z = 0, x in [0, 0.34], y in [0, 0.1], clamped over x <= 0.06. Where the thesis
gives no dimension, docs/cases.md says what was chosen and why. Run it again after changing a
dimension; the scenes cases/sheet*.toml use the files.

The chamber is a parameter: `--chamber-length L` (inside, centred on the outlet), `--chamber-top
Z`, `--chamber-width W` (from y = 0; the outlet and the flaps span it) and `--name PREFIX`
write only the parts that differ from the rig's, as PREFIX_chamber.stl etc. (the others are
shared). Without options it writes the rig of cases/sheet*.toml (a 0.30 x 0.10 m chamber, name
"sheet"). The long, shallow chamber of docs/verification.md ("A chamber whose flow tails
off"), and the half-width slice of it that cases/sheet_tail_slice*.toml run:

  make_sheet_rig.py --chamber-length 0.60 --chamber-top 0.70 --name sheet_tail
  make_sheet_rig.py --chamber-length 0.60 --chamber-top 0.70 --chamber-width 0.05 \
                    --name sheet_tail_slice
"""
import argparse
import os

T_SHEET = 0.00075          # sheet thickness, m (table 5.1)
L_SHEET, W_SHEET = 0.34, 0.10
L_CLAMP = 0.06             # clamped length (table 5.1: 60 x 100 mm)
X_OUTLET = 0.20            # outlet centre line: the middle of the free span [0.06, 0.34]
OUTLET = 0.04              # outlet length (table 5.1)
Z_OUTLET = 0.36            # underside of the hand slides = falling height above the sheet
GAP = 0.012                # calibrated gap between slides and flaps (table 5.2)
CHAMBER_X = (0.05, 0.35)   # inside of the upper chamber, 0.30 m long ...
CHAMBER_Y = (0.0, 0.10)    # ... and as wide as the sheet
CHAMBER_TOP = 0.83         # 0.465 m above the slides: room to pour 6 kg (8.1 l) in
WALL = 0.005               # thickness of chamber walls and slides
FLAP_LEN = 0.08            # each flap: from its hinge to the centre line
FLAP_T = 0.003
HOUSING_BOTTOM = 0.26      # the flap housing ends below the opened flaps (z = 0.268)
JAW_H = 0.02               # clamp jaw height above and below the sheet
BIN_LO = (-0.15, -0.25, -0.35)
BIN_HI = (0.55, 0.35, 0.25)


def box(lo, hi, open_top=False):
    """Triangles of the box surface [lo, hi] (outward normals; open_top drops z = hi)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = []
    for k, (a, b, c, d) in enumerate(quads):
        if open_top and k == 1:
            continue
        tris += [(v[a], v[b], v[c]), (v[a], v[c], v[d])]
    return tris


def parts(chamber_x=CHAMBER_X, top=CHAMBER_TOP, chamber_y=CHAMBER_Y):
    x0, x1 = chamber_x
    y0, y1 = chamber_y
    xl, xr = X_OUTLET - OUTLET / 2, X_OUTLET + OUTLET / 2
    z_slide_top = Z_OUTLET + WALL
    z_flap = Z_OUTLET - GAP
    hinge_l, hinge_r = X_OUTLET - FLAP_LEN, X_OUTLET + FLAP_LEN
    chamber = (box((x0 - WALL, y0 - WALL, Z_OUTLET), (x0, y1 + WALL, top))
               + box((x1, y0 - WALL, Z_OUTLET), (x1 + WALL, y1 + WALL, top))
               + box((x0 - WALL, y0 - WALL, HOUSING_BOTTOM), (x1 + WALL, y0, top))
               + box((x0 - WALL, y1, HOUSING_BOTTOM), (x1 + WALL, y1 + WALL, top)))
    slides = (box((x0, y0, Z_OUTLET), (xl, y1, z_slide_top))
              + box((xr, y0, Z_OUTLET), (x1, y1, z_slide_top))
              + box((hinge_l - WALL, y0, z_flap), (hinge_l, y1, Z_OUTLET))
              + box((hinge_r, y0, z_flap), (hinge_r + WALL, y1, Z_OUTLET)))
    flap_l = box((hinge_l, y0, z_flap - FLAP_T), (X_OUTLET, y1, z_flap))
    flap_r = box((X_OUTLET, y0, z_flap - FLAP_T), (hinge_r, y1, z_flap))
    h = T_SHEET / 2
    frame = (box((-0.01, -0.01, h), (L_CLAMP, W_SHEET + 0.01, h + JAW_H))
             + box((-0.01, -0.01, -h - JAW_H), (L_CLAMP, W_SHEET + 0.01, -h))
             + box((-0.05, -0.01, BIN_LO[2]), (-0.01, W_SHEET + 0.01, h + JAW_H)))
    bin_ = box(BIN_LO, BIN_HI, open_top=True)
    return {"sheet_chamber": chamber, "sheet_slides": slides, "sheet_flap_left": flap_l,
            "sheet_flap_right": flap_r, "sheet_frame": frame, "sheet_bin": bin_}


def normal(a, b, c):
    u = [b[i] - a[i] for i in range(3)]
    w = [c[i] - a[i] for i in range(3)]
    n = (u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0])
    length = sum(x * x for x in n) ** 0.5
    return tuple(x / length for x in n)


def write(path, name, tris):
    with open(path, "w") as out:
        out.write(f"solid {name}\n")
        for t in tris:
            out.write("  facet normal %.9g %.9g %.9g\n    outer loop\n" % normal(*t))
            for p in t:
                out.write("      vertex %.9g %.9g %.9g\n" % p)
            out.write("    endloop\n  endfacet\n")
        out.write(f"endsolid {name}\n")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default=here, help="where the STL files go (default: here)")
    ap.add_argument("--chamber-length", type=float, default=CHAMBER_X[1] - CHAMBER_X[0],
                    help="inside length of the upper chamber along x, m, centred on the outlet")
    ap.add_argument("--chamber-top", type=float, default=CHAMBER_TOP, help="top of the chamber walls, m")
    ap.add_argument("--chamber-width", type=float, default=CHAMBER_Y[1] - CHAMBER_Y[0],
                    help="inside width along y, m, from y = 0 (the outlet and flaps span it)")
    ap.add_argument("--name", default="sheet",
                    help="file prefix; not 'sheet': only the parts that differ from the rig's")
    a = ap.parse_args()
    half = a.chamber_length / 2
    if not (OUTLET / 2 + WALL < half and Z_OUTLET + WALL < a.chamber_top
            and 0 < a.chamber_width <= W_SHEET):
        ap.error(f"--chamber-length must exceed {OUTLET + 2 * WALL} m, --chamber-top "
                 f"{Z_OUTLET + WALL} m and --chamber-width lie in (0, {W_SHEET}] m (got "
                 f"{a.chamber_length}, {a.chamber_top}, {a.chamber_width})")
    if half > X_OUTLET - BIN_LO[0] or half > BIN_HI[0] - X_OUTLET:
        ap.error(f"--chamber-length {a.chamber_length} m: the chamber must stay above the bin "
                 f"(x {BIN_LO[0]} to {BIN_HI[0]} m): at most {2 * (X_OUTLET - BIN_LO[0]):.2f} m")
    default_length = abs(a.chamber_length - (CHAMBER_X[1] - CHAMBER_X[0])) < 1e-12
    default_width = abs(a.chamber_width - (CHAMBER_Y[1] - CHAMBER_Y[0])) < 1e-12
    rig = parts(CHAMBER_X if default_length else (X_OUTLET - half, X_OUTLET + half), a.chamber_top,
                CHAMBER_Y if default_width else (0.0, a.chamber_width))
    default = parts()
    for part, tris in rig.items():
        if a.name != "sheet" and tris == default[part]:
            continue
        name = a.name + part[len("sheet"):]
        write(os.path.join(a.folder, name + ".stl"), name, tris)


if __name__ == "__main__":
    main()
