"""Where a sleeper's bed gives way: the rocks' mean vertical displacement under and beside the
sleeper, by position along it and by height, between two moments of a run (issue 38).

usage: sleeper_bed_motion.py OUTPUT_DIR [--from T0] [--to T1 [T2 ...]] [--bin DX]
           [--layers Z0:Z1,...] [--bands D0:D1,...] [--phi-layer Z0:Z1] [--scene SCENE]
           [--set KEY=VALUE ...] [--json FILE]

OUTPUT_DIR is a sleeper load case's output folder (cases/sleeper*.toml) with particles.xdmf
and fem.xdmf. The sleeper's footprint is taken from the FEM mesh at T0 (its nodes' x range and
its middle in y, the centre line), the rocks from the particle snapshots nearest to T0 and to
each T1 (the times used are printed). Each rock is placed by its centre at T0: in an x bin of
width DX along the sleeper (from its end at the smaller x), in a band by its distance from the
centre line (both sides; default 0-0.1 m, under a 0.2 m wide sleeper, 0.1-0.2 and 0.2-0.5 m)
and in a layer by its height (absolute z, default 0.70-0.85, 0.60-0.70 and 0.45-0.60 m, the
sleeper's layer down to the cells of the 0.13 m chain). For each bin, band and layer the mean
of z(T1) - z(T0) of its rocks is printed in mm, with the count; beside it, for each x bin of
the first band, the solid fraction at T0 of the --phi-layer heights (default 0.55-0.75 m): the
rocks' volume (mass / their material's density, the scene's dem.materials) over the box's,
each rock counted whole where its centre lies, so a box of a few hundred rocks scatters by a
few per cent. The scene is OUTPUT_DIR/run.json's, else --scene; the run's --set overrides are
applied, then those given here. --json writes every number. Exit status 2 on a missing file,
field or key, or a time outside the run.

Made for the question "which part of the bed under the sleeper went first" (docs/cases.md,
"Full scale: the cells 0.26 m deep"): a reading of the particle snapshots, not a measurement
of the bed's strength.
"""

import argparse
import json
import os
import sys

from demfem_post.needs import need_or_exit, tool_errors

TOOL = "sleeper_bed_motion.py"


def ranges(text, what):
    """'a:b,c:d' as [(a, b), (c, d)] with a < b; ValueError naming the option otherwise."""
    out = []
    for part in text.split(","):
        lo, sep, hi = part.partition(":")
        try:
            pair = (float(lo), float(hi))
        except ValueError:
            raise ValueError(f"{what} {text!r}: expected LOW:HIGH[,LOW:HIGH...] in m") from None
        if not sep or not pair[0] < pair[1]:
            raise ValueError(f"{what} {text!r}: each range LOW:HIGH needs LOW < HIGH (m)")
        out.append(pair)
    return out


def parse(argv):
    p = argparse.ArgumentParser(prog=TOOL, description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("output", help="the load case's output folder")
    p.add_argument("--from", dest="t0", type=float, default=0.2,
                   help="the reference moment, s (default 0.2, the load's start)")
    p.add_argument("--to", dest="t1", type=float, nargs="+", default=[0.4],
                   help="the later moments, s (default 0.4)")
    p.add_argument("--bin", type=float, default=0.25, help="x bin width along the sleeper, m")
    p.add_argument("--layers", default="0.70:0.85,0.60:0.70,0.45:0.60",
                   help="height ranges of the rocks' centres at T0, m")
    p.add_argument("--bands", default="0:0.1,0.1:0.2,0.2:0.5",
                   help="distance ranges from the sleeper's centre line, m")
    p.add_argument("--phi-layer", default="0.55:0.75",
                   help="the heights of the solid fraction at T0, m")
    p.add_argument("--scene", help="the scene, when the folder has no run.json naming it")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a scene override, as demfem run --set")
    p.add_argument("--json", help="write the numbers to this file")
    a = p.parse_args(argv)
    if a.bin <= 0:
        p.error(f"--bin {a.bin}: the bin width must be > 0 m")
    try:
        a.layers = ranges(a.layers, "--layers")
        a.bands = ranges(a.bands, "--bands")
        a.phi_layer = ranges(a.phi_layer, "--phi-layer")[0]
    except ValueError as e:
        p.error(str(e))
    if any(lo < 0 for lo, _ in a.bands):
        p.error("--bands: a distance from the centre line is >= 0 m")
    return a


def bed_motion(np, x0, z0, z1, volume, footprint, dx, layers, bands, phi_layer):
    """The binned mean displacements and solid fractions. x0: the rocks' (x, y) at T0 as an
    (n, 2) array; z0, z1: their heights at T0 and T1; volume: each rock's volume (m^3);
    footprint: (x_lo, x_hi, y_centre). Returns {'bins': [(x_lo, x_hi)], 'dz_mm':
    [band][layer][bin] (None where empty), 'count': same shape, 'phi': [bin] of the first band}."""
    x_lo, x_hi, yc = footprint
    n_bins = max(1, int(round((x_hi - x_lo) / dx)))
    edges = x_lo + dx * np.arange(n_bins + 1)
    edges[-1] = max(edges[-1], x_hi)
    which = np.searchsorted(edges, x0[:, 0], side="right") - 1
    inside = (x0[:, 0] >= x_lo) & (which >= 0) & (which < n_bins)
    dist = np.abs(x0[:, 1] - yc)
    dz = (z1 - z0) * 1e3
    result = {"bins": [(float(edges[k]), float(edges[k + 1])) for k in range(n_bins)],
              "dz_mm": [], "count": [], "phi": []}
    for lo, hi in bands:
        in_band = inside & (dist >= lo) & (dist < hi)
        rows_dz, rows_n = [], []
        for zl, zh in layers:
            sel = in_band & (z0 >= zl) & (z0 < zh)
            n = np.bincount(which[sel], minlength=n_bins)
            s = np.bincount(which[sel], weights=dz[sel], minlength=n_bins)
            rows_dz.append([float(s[k] / n[k]) if n[k] else None for k in range(n_bins)])
            rows_n.append([int(v) for v in n])
        result["dz_mm"].append(rows_dz)
        result["count"].append(rows_n)
    lo, hi = bands[0]
    sel = inside & (dist >= lo) & (dist < hi) & (z0 >= phi_layer[0]) & (z0 < phi_layer[1])
    v = np.bincount(which[sel], weights=volume[sel], minlength=n_bins)
    box = (edges[1:] - edges[:-1]) * 2.0 * (hi - lo) * (phi_layer[1] - phi_layer[0])
    result["phi"] = [float(v[k] / box[k]) for k in range(n_bins)]
    return result


def footprint_at(np, run, t):
    fem = run.fem(t)
    pts = np.asarray(fem.points, dtype=float)
    if "displacement" in fem.point_data:
        pts = pts + np.asarray(fem["displacement"], dtype=float)
    return float(pts[:, 0].min()), float(pts[:, 0].max()), 0.5 * float(pts[:, 1].min() + pts[:, 1].max())


def rocks_at(np, run, t, densities):
    times = run.fields("particles").times
    if not times:
        raise ValueError(f"{run.path}: the particle output has no snapshots")
    if not times[0] - 1e-9 <= t <= times[-1] + 1e-9:
        raise ValueError(f"{run.path}: {t:g} s is outside the particle output's times "
                         f"({times[0]:g}-{times[-1]:g} s)")
    snap = run.particles(t)
    order = np.argsort(np.asarray(snap["id"]).astype(np.int64))
    pos = np.asarray(snap.points, dtype=float)[order]
    mass = np.asarray(snap["mass"], dtype=float)[order]
    mat = np.asarray(snap["material"]).astype(np.int64)[order]
    ids = np.asarray(snap["id"]).astype(np.int64)[order]
    if mat.min() < 0 or mat.max() >= len(densities):
        raise ValueError(f"{run.path}: particle material {int(mat.max())} not in the scene's "
                         f"{len(densities)} dem.materials")
    rho = np.asarray(densities)[mat]
    if not np.all(rho > 0):
        k = int(mat[~(rho > 0)][0])
        raise ValueError(f"the scene's dem.materials[{k}] has no density > 0 (kg/m^3), and "
                         f"rocks at {snap.time:g} s are of it")
    return snap.time, ids, pos, mass / rho


def table(a, footprint, t0, times, results):
    x_lo, x_hi, yc = footprint
    print(f"sleeper footprint at {t0:g} s: x {x_lo:.3f}-{x_hi:.3f} m, centre line y = {yc:.3f} m")
    for t1, r in zip(times, results):
        print(f"\nmean vertical displacement of the rocks, {t0:g} -> {t1:g} s (mm; rocks)")
        for b, (lo, hi) in enumerate(a.bands):
            print(f"  {lo:g}-{hi:g} m from the centre line")
            head = "    x (m)       " + "".join(f"  z {zl:.2f}-{zh:.2f}  " for zl, zh in a.layers)
            print(head + (f"  phi {a.phi_layer[0]:.2f}-{a.phi_layer[1]:.2f} at {t0:g} s" if b == 0 else ""))
            for k, (xl, xh) in enumerate(r["bins"]):
                cells = ""
                for i in range(len(a.layers)):
                    d, n = r["dz_mm"][b][i][k], r["count"][b][i][k]
                    cells += f"  {'-' if d is None else f'{d:7.1f}':>7} ({n:4d})"
                print(f"    {xl:.2f}-{xh:.2f}  {cells}" + (f"   {r['phi'][k]:.3f}" if b == 0 else ""))


def main(argv):
    a = parse(argv)
    with tool_errors(TOOL):
        np = need_or_exit(TOOL, "numpy", "python3-numpy")
        from demfem_post import Run, load_scene, run_overrides
        run = Run(a.output)
        # the run's own scene and --set overrides (run.json), or --scene with them
        scene = (load_scene(a.scene, run_overrides(a.output) + a.set) if a.scene
                 else run.scene(a.set))
        # the walls' materials may have no density: a rock of one is refused in rocks_at
        densities = [float(m.get("density", "nan")) for m in scene["dem"]["materials"]]
        footprint = footprint_at(np, run, a.t0)
        t0, ids0, p0, vol = rocks_at(np, run, a.t0, densities)
        times, results = [], []
        for t in a.t1:
            t1, ids1, p1, _ = rocks_at(np, run, t, densities)
            if not np.array_equal(ids0, ids1):
                raise ValueError(f"{a.output}: the rocks at {t0:g} s and {t1:g} s differ "
                                 f"({len(ids0)} against {len(ids1)}): rocks removed between them")
            times.append(t1)
            results.append(bed_motion(np, p0[:, :2], p0[:, 2], p1[:, 2], vol, footprint, a.bin,
                                      a.layers, a.bands, a.phi_layer))
        table(a, footprint, t0, times, results)
        if a.json:
            with open(a.json, "w") as f:
                json.dump({"output": os.path.abspath(a.output), "from_s": t0,
                           "footprint": dict(zip(("x_lo", "x_hi", "y_centre"), footprint)),
                           "layers": a.layers, "bands": a.bands, "phi_layer": a.phi_layer,
                           "moments": [dict(to_s=t, **r) for t, r in zip(times, results)]},
                          f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
