#!/usr/bin/python3
"""Makes the case gallery's pictures (docs/gallery.md): for every scene of cases/, examples/
and the tutorials, a short run of it into OUT/NAME, then a picture of its last output frame
(tools/gallery_render.py under pvbatch and xvfb-run) into docs/figures/gallery/NAME.png.

"Short": a scene of a few seconds runs whole; a longer one runs to the end time given in
SCENES below (its first moments: a picture of how it starts, said in the gallery). Particle
output is switched on where the scene switches it off (`--set dem.output.particles=true`),
so that the picture shows the particles. Scenes that load a prepared state ([dem.load]) need
that state first, which their prepare scenes make (minutes to hours): they are pictured only
with --with-prepare, else listed as skipped. Run from anywhere:

    python3 tools/gallery_pictures.py [--build build] [--only NAME ...] [--with-prepare]

Needs the build (demfem_run), pvbatch (Debian: python3-paraview) and xvfb-run (xvfb). Prints
one line per scene: the picture written, or why none was. Exit status 1 when a picture that
was asked for could not be made.
"""

import argparse
import os
import shutil
import subprocess
import sys
import time
import tomllib

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# scene (from the top of the repository) -> (end time of the short run in s, or None for the
# scene's own; further --set overrides). The gallery says which pictures are of a scene's
# first moments.
SCENES = {
    "cases/beam_fixed_ci.toml": (None, []),
    "cases/beam_fixed.toml": (None, []),
    "cases/beam_fixed_72kg.toml": (None, []),
    "cases/beam_dynamic_jit.toml": (None, []),
    "cases/beam_dynamic_predictive.toml": (None, []),
    "cases/beam_dynamic_ci.toml": (None, []),
    "cases/beam_checkpoint_ci.toml": (None, []),
    "cases/beam_sweep_ci.toml": (None, []),
    "cases/beam_pour_ci.toml": (None, []),
    "cases/beam_chain_ci.toml": (None, []),
    "cases/beam_modes.toml": (None, []),
    "cases/beam_drop.toml": (None, []),
    "cases/plate_bed.toml": (None, []),
    "cases/heap_repose.toml": (0.4, []),
    "cases/heap_repose_rocks.toml": (0.15, []),
    "cases/heap_repose_rocks_ref.toml": (0.4, []),
    "cases/rocks_box.toml": (0.3, []),
    "cases/periodic_block.toml": (None, []),
    "cases/periodic_block_tiled.toml": (None, []),
    "cases/sleeper_prep_poured_small.toml": (1.0, []),
    "cases/sleeper_prep_packed_small.toml": (0.8, []),
    "cases/sleeper_prep_block_mid.toml": (0.3, []),
    "cases/sleeper_prep_tiled_mid.toml": (0.02, []),
    "cases/sleeper_prep_poured_mid.toml": (0.3, []),
    "cases/sleeper_prep_landed_mid.toml": (0.01, []),
    "cases/sleeper_prep_block_poured_mid.toml": (0.3, []),
    "cases/sleeper_prep_block_compacted_mid.toml": (0.3, []),
    "cases/sheet_fill_ci.toml": (0.1, []),
    "cases/sheet_fill.toml": (0.005, []),
    "cases/sheet_fill_coarse.toml": (0.01, []),
    "cases/sheet_fill_tail_coarse.toml": (0.005, []),
    "cases/sheet_fill_tail_slice_coarse.toml": (0.01, []),
    "cases/sheet_ci.toml": (0.1, []),
    "cases/sheet.toml": (0.002, []),
    "cases/sheet_coarse.toml": (0.002, []),
    "cases/sheet_tail_coarse.toml": (0.002, []),
    "cases/sheet_tail_flow_coarse.toml": (0.002, []),
    "cases/sheet_tail_slice_flow_coarse.toml": (0.002, []),
    "cases/sleeper_bed1_mini.toml": (None, []),
    "cases/sleeper_bed1_ci.toml": (0.7, ["dem.settle_time=0"]),  # the rocks have fallen
    "cases/sleeper_pour1.toml": (0.2, []),
    "cases/sleeper_bed2_mini.toml": (0.002, []),
    "cases/sleeper_land_mini.toml": (0.01, []),
    "cases/sleeper_bed2_ci.toml": (0.002, []),
    "cases/sleeper_bed2_ci_packed.toml": (0.002, []),
    "cases/sleeper_pour2_ci_fast.toml": (None, []),
    "cases/sleeper_bed2_ci_fast.toml": (0.002, []),
    "cases/sleeper_bed1.toml": (0.001, []),
    "cases/sleeper_pour2.toml": (0.002, []),
    "cases/sleeper_pour2_packed.toml": (0.002, []),
    "cases/sleeper_bed2.toml": (0.001, []),
    "cases/sleeper_mini.toml": (0.1, []),
    "cases/sleeper_ci.toml": (0.1, []),
    "cases/sleeper_ci_100.toml": (0.1, []),
    "cases/sleeper.toml": (0.002, []),
    "cases/sleeper_bed1_cells026.toml": (0.001, []),
    "cases/sleeper_pour2_cells026.toml": (0.002, []),
    "cases/sleeper_bed2_cells026.toml": (0.001, []),
    "cases/sleeper_block1.toml": (0.002, []),
    "cases/sleeper_block1_compact.toml": (1.202, []),
    "cases/sleeper_pour1_tiled.toml": (0.002, []),
    "cases/sleeper_bed1_tiled.toml": (0.001, []),
    "cases/sleeper_pour2_tiled.toml": (0.002, []),
    "cases/sleeper_compact2_tiled.toml": (0.002, []),
    "cases/sleeper_bed2_tiled.toml": (0.001, []),
    "cases/sleeper_land_tiled.toml": (0.001, []),
    "cases/sleeper_tiled.toml": (0.002, []),
    "cases/sleeper_bed1_tiled_cells026.toml": (0.001, []),
    "cases/sleeper_pour2_tiled_cells026.toml": (0.002, []),
    "cases/sleeper_compact2_tiled_cells026.toml": (0.002, []),
    "cases/sleeper_bed2_tiled_cells026.toml": (0.001, []),
    "cases/sleeper_land_tiled_cells026.toml": (0.001, []),
    "cases/sleeper_tiled_cells026.toml": (0.002, []),
    "cases/sleeper_cells026.toml": (0.002, []),
    "examples/python_spring_plate/static_ci.toml": (None, []),
    "examples/python_spring_plate/dynamic_ci.toml": (None, []),
    "examples/python_dem_spheres/beam_spheres_ci.toml": (None, []),
    "examples/fenicsx_beam/beam_fixed_ci.toml": (None, []),
    "examples/liggghts_dem/beam_fixed_ci.toml": (None, []),
    "examples/liggghts_dem/beam_spheres_ci.toml": (None, []),
    "examples/liggghts_dem/sheet_flow_ci.toml": (0.25, []),  # the stream has reached the sheet
    "examples/liggghts_dem/sheet_flow_ci_dem_server.toml": (0.25, []),
    "examples/cpp_spring_bed/static_ci.toml": (None, []),
    "docs/tutorials/plank.toml": (None, []),
    "docs/tutorials/plank_rocks.toml": (None, []),
}

# Scenes that need a program built outside demfem's build: pictured only when it is given
# (--spring-bed PATH: the scene's own command with that program).
NEEDS_PROGRAM = {"examples/cpp_spring_bed/static_ci.toml": "spring_bed (examples/cpp_spring_bed, "
                 "built against the installed SDK: docs/backends.md; --spring-bed PATH)"}


def picture_name(scene):
    return os.path.splitext(scene)[0].replace("/", "_").removeprefix("cases_")


def overrides(scene, end_time, sets):
    with open(os.path.join(REPO, scene), "rb") as f:
        doc = tomllib.load(f)
    out = list(sets)
    if end_time is not None:
        out.append(f"run.end_time={end_time!r}")
    if doc.get("dem", {}).get("output", {}).get("particles") is False:
        out.append("dem.output.particles=true")
    return out, "load" in doc.get("dem", {})


def run_scene(demfem_run, bin_dir, scene, out_dir, sets, limit):
    args = [demfem_run, os.path.join(REPO, scene), "--bin-dir", bin_dir, "--output-dir",
            out_dir, "--quiet", "--no-post"] + [a for s in sets for a in ("--set", s)]
    # --no-post: a report of a run cut short would fail (and the picture needs none)
    env = dict(os.environ)
    if os.geteuid() == 0:  # Open MPI (the LIGGGHTS examples' mpirun) refuses root without these
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    start = time.monotonic()
    try:
        # from the top of the tree, as the gallery's commands: prepare scenes write into out/
        r = subprocess.run(args, capture_output=True, text=True, timeout=limit, env=env, cwd=REPO)
    except subprocess.TimeoutExpired:
        return f"the run took longer than {limit} s (--run-limit)"
    if r.returncode != 0:
        return f"the run ended with status {r.returncode}: {r.stderr.strip()[-400:]}"
    return time.monotonic() - start


def render(out_dir, png, title):
    """pvbatch under xvfb-run; a second try when the first loses its virtual display (two
    xvfb-runs can pick the same one: ParaView then aborts with a bad X connection)."""
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", "pvbatch",
           os.path.join(REPO, "tools", "gallery_render.py"), out_dir, png, title]
    for _ in range(3):
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if r.returncode == 0 and os.path.isfile(png):
            return None
    return f"pvbatch failed ({r.returncode}): {(r.stdout + r.stderr).strip()[-400:]}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--build", default=os.path.join(REPO, "build"), help="the build folder")
    ap.add_argument("--out", default=os.path.join(REPO, "out", "gallery"),
                    help="where the short runs write (default out/gallery)")
    ap.add_argument("--figures", default=os.path.join(REPO, "docs", "figures", "gallery"),
                    help="where the pictures go (default docs/figures/gallery)")
    ap.add_argument("--only", nargs="+", default=None, metavar="NAME",
                    help="only these scenes (picture names, e.g. beam_fixed_ci, or paths)")
    ap.add_argument("--with-prepare", action="store_true",
                    help="also the scenes that load a prepared state (runs their prepare scenes)")
    ap.add_argument("--spring-bed", default=None, metavar="PATH",
                    help="the C++ example's program (examples/cpp_spring_bed, built out of tree)")
    ap.add_argument("--run-limit", type=float, default=900.0, metavar="S",
                    help="stop a short run after S seconds of wall time (its scene gets no picture)")
    args = ap.parse_args()
    for tool in ("xvfb-run", "pvbatch"):
        if shutil.which(tool) is None:
            sys.exit(f"gallery_pictures.py: {tool} is missing: install Debian's "
                     f"{'xvfb' if tool == 'xvfb-run' else 'python3-paraview'} (./demfem setup)")
    demfem_run = os.path.join(args.build, "bin", "demfem_run")
    if not os.access(demfem_run, os.X_OK):
        sys.exit(f"gallery_pictures.py: no {demfem_run}: build first (./demfem build)")
    os.makedirs(args.figures, exist_ok=True)
    failed = 0
    for scene, (end_time, sets) in SCENES.items():
        name = picture_name(scene)
        if args.only and name not in args.only and scene not in args.only:
            continue
        sets, loads = overrides(scene, end_time, sets)
        if loads and not args.with_prepare:
            print(f"{scene}: skipped (it loads a prepared state; --with-prepare runs its prepare scenes)")
            continue
        if scene in NEEDS_PROGRAM:
            if not args.spring_bed:
                print(f"{scene}: skipped (needs {NEEDS_PROGRAM[scene]})")
                continue
            with open(os.path.join(REPO, scene), "rb") as f:
                command = tomllib.load(f)["fem"]["command"]
            command = [os.path.abspath(args.spring_bed)] + command[1:]
            sets.append("fem.command=[" + ", ".join(f'"{c}"' for c in command) + "]")
        out_dir = os.path.join(args.out, name)
        took = run_scene(demfem_run, os.path.join(args.build, "bin"), scene, out_dir, sets,
                         args.run_limit)
        if isinstance(took, str):
            print(f"{scene}: no picture: {took}", flush=True)
            failed += 1
            continue
        png = os.path.join(args.figures, name + ".png")
        error = render(out_dir, png, scene)
        if error:
            print(f"{scene}: no picture: {error}", flush=True)
            failed += 1
            continue
        print(f"{scene}: wrote {os.path.relpath(png, REPO)} (run {took:.1f} s; "
              f"{' '.join(sets) or 'as the scene says'})", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
