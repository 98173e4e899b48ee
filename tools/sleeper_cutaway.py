"""ParaView pictures of a sleeper run's bed cut open under the sleeper (issue 38; thesis fig. 6.13).

usage: xvfb-run -a -s "-screen 0 1600x1000x24" pvbatch tools/sleeper_cutaway.py OUTPUT_DIR
           [--time T] [--field displacement|velocity] [--png PREFIX] [--size W H]

OUTPUT_DIR is a sleeper load case's output folder (cases/sleeper*.toml) with particles.xdmf,
fem.xdmf, walls_<cell>.xdmf and the sleeper_report.json of tools/sleeper_report.py. Each file is
opened with the reader ParaView picks for it (OpenDataFile: Xdmf3ReaderS), at the written time
nearest to T; T defaults to the report's moment of the 132 kN level on the ramp before the
cycles (json load_levels; 33 kN per seat on the CI scale). The bed is cut open along the
sleeper's long axis at the sleeper's centre line y_c (the middle of the FEM mesh in y): the
rocks whose centre lies at y >= y_c are shown whole (a plane clip would leave hollow shells of
the rocks' surfaces), coloured by their centre's displacement since the load's start
(json load_start_s; the particle output holds no contact forces) or, with --field velocity, by
the speed of each surface point (the output's velocity, thesis fig. 6.13's field); the sleeper
is clipped at y_c, drawn in its displaced place (Warp By Vector, displacement, factor 1) and
coloured by its elements' largest principal strain (microstrain); the pressure cells (walls
whose name starts with "cell") are drawn whole, in one colour, their pressures at that time
(sensor_<cell>.csv, top-face force / area) in the caption.
Writes PREFIX_front.png (the cut face, seen across the bed) and PREFIX_oblique.png (a view from
the front and above); PREFIX defaults to OUTPUT_DIR/sleeper_cutaway. Exit status 2 on a
missing file or field, or a time outside the run.

On a loaded machine pvbatch (ParaView 5.11 on Xvfb) now and then aborts at its start with
"vtkXOpenGLRenderWindow: bad X server connection" while it creates its view (measured beside three
solver runs on two cores: 3 of the first 4 single starts, none of the next 5; 5 of 32 starts
four at once); run it again (tests/system/check_sleeper_cutaway.py tries three times). Where it
keeps aborting (measured beside a test-suite run: three tries of `xvfb-run -a`, one of `-n 157`),
start the X server yourself and give it time: `Xvfb :158 -screen 0 1600x1000x24 &`, then after
a few seconds `DISPLAY=:158 pvbatch tools/sleeper_cutaway.py ...`.
"""

import argparse
import csv
import json
import os
import sys

from demfem_post.needs import need_or_exit

# ParaView's Python, run by pvbatch under xvfb-run (Debian: paraview, xvfb)
PARAVIEW = ("paraview and xvfb", "xvfb-run -a pvbatch")
pv = need_or_exit("sleeper_cutaway.py", "paraview.simple", *PARAVIEW)
servermanager = need_or_exit("sleeper_cutaway.py", "paraview.servermanager", *PARAVIEW)
dsa = need_or_exit("sleeper_cutaway.py", "vtk.numpy_interface.dataset_adapter", *PARAVIEW)
np = need_or_exit("sleeper_cutaway.py", "numpy", "python3-numpy", "xvfb-run -a pvbatch")


class InputError(Exception):
    """A missing file or field, or a time outside the run: exit status 2."""


def parse(argv):
    ap = argparse.ArgumentParser(description="ParaView cutaway of a sleeper run's bed")
    ap.add_argument("output")
    ap.add_argument("--time", type=float, default=None,
                    help="s (default: the 132 kN level before the cycles, from the report)")
    ap.add_argument("--field", choices=("displacement", "velocity"), default="displacement")
    ap.add_argument("--png", default=None, help="prefix of the PNGs")
    ap.add_argument("--size", type=int, nargs=2, default=(1400, 620), metavar=("W", "H"))
    return ap.parse_args(argv)


def run_name(out):
    """The run's scene file (run.json), else its output folder's name, for the caption."""
    try:
        with open(os.path.join(out, "run.json")) as f:
            return os.path.basename(json.load(f)["scene"])
    except (OSError, KeyError, ValueError):
        return os.path.basename(os.path.normpath(out))


def need_file(out, name):
    path = os.path.join(out, name)
    if not os.path.isfile(path):
        raise InputError(f"{path}: not found (a sleeper run's output folder and "
                         "tools/sleeper_report.py's report are needed)")
    return path


def picture_time(report, requested):
    """(time wanted, words for the caption) from --time or the report's 132 kN moment."""
    if requested is not None:
        return requested, "the time asked for"
    for m in report.get("load_levels", []):
        if m["level_kN"] == 132.0 and m["stage"] == "before":
            return m["time"], (f"132 kN level before the cycles ({m['load_per_seat_N'] / 1e3:.3g}"
                               " kN per rail seat in this scene)")
    raise InputError("the report has no 132 kN moment before the cycles (json load_levels: the "
                     "run ended before it, or the report predates it): give --time")


def nearest_written(reader, t, what):
    times = list(reader.TimestepValues or [0.0])
    if t < times[0] - 1e-9 or t > times[-1] + 1e-9:
        raise InputError(f"{what}: time {t:g} s is outside the written {times[0]:g}-"
                         f"{times[-1]:g} s")
    return min(times, key=lambda s: abs(s - t))


def rock_blocks(reader, t):
    """(centres, surfaces) of the particles at time t: the reader's two pieces, the rocks'
    centres (vertex cells) and their triangle surfaces (each point with its rock's id)."""
    reader.UpdatePipeline(t)
    data = servermanager.Fetch(reader)
    leaves = []
    it = data.NewIterator()
    it.InitTraversal()
    while not it.IsDoneWithTraversal():
        leaves.append(it.GetCurrentDataObject())
        it.GoToNextItem()
    kinds = {2: None, 5: None}  # VTK_VERTEX, VTK_TRIANGLE
    for leaf in leaves:
        if leaf.GetNumberOfCells() and leaf.GetCellType(0) in kinds:
            kinds[leaf.GetCellType(0)] = leaf
    if kinds[2] is None or kinds[5] is None:
        raise InputError(f"particles.xdmf at t = {t:g} s: no rock surfaces (polyhedra) beside "
                         "the centres")
    return kinds[2], kinds[5]


def rock_arrays(leaf):
    w = dsa.WrapDataObject(leaf)
    return np.asarray(w.Points), np.asarray(w.PointData["id"]).astype(np.int64).ravel()


def rows_of(ids, wanted):
    """The row of each id of `wanted` in `ids` (-1 where absent)."""
    order = np.argsort(ids)
    at = np.clip(np.searchsorted(ids, wanted, sorter=order), 0, len(ids) - 1)
    rows = order[at]
    return np.where(ids[rows] == wanted, rows, -1)


def cut_rocks(reader, t, t_ref, y_cut, field):
    """The rocks' surfaces at t whose centre lies at y >= y_cut, with the point array
    rock_displacement_mm (the centre's displacement since t_ref; with field "displacement")
    beside the output's own arrays (velocity: each surface point's)."""
    centres, surfaces = rock_blocks(reader, t)
    x, ids = rock_arrays(centres)
    _, point_ids = rock_arrays(surfaces)
    row = rows_of(ids, point_ids)  # each surface point's rock
    if (row < 0).any():
        raise InputError(f"particles.xdmf at t = {t:g} s: a surface point of a rock without "
                         "a centre")
    wrapped = dsa.WrapDataObject(surfaces)
    if field == "displacement":
        x0, ids0 = rock_arrays(rock_blocks(reader, t_ref)[0])
        start = rows_of(ids0, ids)
        # a rock not there at t_ref (none in a load case) counts from where it is
        moved = np.where((start >= 0)[:, None], x - x0[np.maximum(start, 0)], 0.0)
        wrapped.PointData.append(1e3 * moved[row], "rock_displacement_mm")
    behind = x[:, 1] >= y_cut
    wrapped.PointData.append(behind[row].astype(float), "behind_cut")
    producer = pv.TrivialProducer(registrationName="rocks")
    producer.GetClientSideObject().SetOutput(surfaces)
    producer.UpdatePipeline()
    rocks = pv.Threshold(registrationName="rocks behind the cut", Input=producer,
                         Scalars=["POINTS", "behind_cut"], LowerThreshold=0.5,
                         UpperThreshold=1.5)
    rocks.AllScalars = 1
    return rocks, int(behind.sum()), len(ids)


def cell_pressures(out, cells, t):
    """[(cell, pressure kPa)] at the sensor sample nearest t: the rocks' top-face force over
    the cell's top area (the report's cells), for the caption."""
    res = []
    for c in cells:
        path = os.path.join(out, f"sensor_{c['name']}.csv")
        if not os.path.isfile(path):
            continue
        with open(path) as f:
            rows = list(csv.DictReader(f))
        if rows:
            row = min(rows, key=lambda r: abs(float(r["time"]) - t))
            res.append((c["name"], -float(row["fz"]) / c["area_m2"] / 1e3))
    return res


def black_text(display):
    display.Color = [0.0, 0.0, 0.0]
    display.FontSize = 15


def colour_bar(view, display, field, title, location):
    lut = pv.GetColorTransferFunction(field)
    bar = pv.GetScalarBar(lut, view)
    bar.Title, bar.ComponentTitle = title, ""
    bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    bar.TitleFontSize = bar.LabelFontSize = 14
    bar.Orientation = "Horizontal"
    bar.WindowLocation = location
    bar.ScalarBarLength = 0.28
    bar.RangeLabelFormat = "%.3g"
    display.SetScalarBarVisibility(view, True)
    return lut


def main(argv):
    a = parse(argv)
    out = a.output
    report_path = need_file(out, "sleeper_report.json")
    with open(report_path) as f:
        report = json.load(f)
    want, caption = picture_time(report, a.time)
    parts = pv.OpenDataFile(need_file(out, "particles.xdmf"))
    fem = pv.OpenDataFile(need_file(out, "fem.xdmf"))
    t = nearest_written(parts, want, "particles.xdmf")
    t_fem = nearest_written(fem, t, "fem.xdmf")
    if abs(t - want) > 1e-9:
        print(f"sleeper_cutaway.py: the nearest written time to {want:g} s is {t:g} s "
              "(write more often: run.output_interval and dem.output.interval)", file=sys.stderr)
        caption += f", written at t = {t:g} s (wanted {want:g} s)"
    else:
        caption += f", t = {t:g} s"
    t_ref = nearest_written(parts, report.get("load_start_s", 0.0), "particles.xdmf")
    fem.UpdatePipeline(t_fem)
    lo_hi = fem.GetDataInformation().GetBounds()
    y_cut = 0.5 * (lo_hi[2] + lo_hi[3])
    return draw(a, out, report, parts, fem, t, t_ref, y_cut, caption)


def show_sleeper(view, fem, y_cut, t):
    """The sleeper's half at y >= y_cut, displaced, coloured by the largest principal strain
    of its elements (microstrain): from the strain tensor (the largest eigenvalue, as the FEM
    computes max_principal_strain), or the written max_principal_strain, else by the
    displacement's magnitude when neither field is written."""
    half = pv.Clip(registrationName="sleeper, y >= centre", Input=fem, ClipType="Plane")
    half.ClipType.Origin = [0.0, y_cut, 0.0]
    half.ClipType.Normal = [0.0, 1.0, 0.0]
    half.Invert = 0  # keep the side the normal points to
    moved = pv.WarpByVector(registrationName="displaced", Input=half,
                            Vectors=["POINTS", "displacement"])
    moved.UpdatePipeline(t)
    cells = moved.CellData.keys()
    if "strain" in cells or "max_principal_strain" in cells:
        expression = ("max(eigenvalue(strain), axis=1)" if "strain" in cells
                      else "max_principal_strain")
        shown = pv.PythonCalculator(registrationName="microstrain", Input=moved,
                                    ArrayAssociation="Cell Data", ArrayName="strain_micro",
                                    Expression=f"{expression} * 1e6")
        field, title = ("CELLS", "strain_micro"), "sleeper: largest principal strain (microstrain)"
    else:
        shown = moved
        field, title = ("POINTS", "displacement", "Magnitude"), "sleeper: displacement (m)"
    d = pv.Show(shown, view)
    pv.ColorBy(d, field)
    d.RescaleTransferFunctionToDataRange(True, False)
    lut = colour_bar(view, d, field[1], title, "Lower Left Corner")
    lut.ApplyPreset("Cool to Warm", True)
    return shown


def show_rocks(view, rocks, field):
    d = pv.Show(rocks, view)
    name = "rock_displacement_mm" if field == "displacement" else "velocity"
    pv.ColorBy(d, ("POINTS", name, "Magnitude"))
    d.RescaleTransferFunctionToDataRange(True, False)
    title = ("rocks: displacement of the centre since the load's start (mm)"
             if field == "displacement" else "rocks: speed (m/s)")
    lut = colour_bar(view, d, name, title, "Lower Right Corner")
    lut.ApplyPreset("Viridis (matplotlib)", True)
    return d


def show_walls(view, out, report, top):
    """The pressure cells (solid) and the box (wireframe, cut at `top`)."""
    for c in report.get("cells", {}).get("cells", []):
        cell = pv.OpenDataFile(need_file(out, f"walls_{c['name']}.xdmf"))
        d = pv.Show(cell, view)
        d.AmbientColor = d.DiffuseColor = [0.85, 0.1, 0.55]
        pv.ColorBy(d, None)
    box_path = os.path.join(out, "walls_box.xdmf")
    if os.path.isfile(box_path):
        low = pv.Clip(registrationName="box, below the sleeper's top",
                      Input=pv.OpenDataFile(box_path), ClipType="Plane")
        low.ClipType.Origin = [0.0, 0.0, top]
        low.ClipType.Normal = [0.0, 0.0, 1.0]
        d = pv.Show(low, view)
        d.SetRepresentationType("Outline")
        d.AmbientColor = d.DiffuseColor = [0.45, 0.45, 0.45]
        pv.ColorBy(d, None)


def caption(view, text):
    t = pv.Text(registrationName="caption", Text=text)
    d = pv.Show(t, view)
    black_text(d)
    d.WindowLocation = "Upper Left Corner"
    d.Justification = "Left"
    return t


def aim(view, lo, hi, name):
    """The camera on the box lo-hi (the bed under the sleeper and the sleeper): `front` looks
    across the bed (+y) at the cut face in parallel projection, `oblique` from the front,
    above and the left."""
    centre = [0.5 * (a + b) for a, b in zip(lo, hi)]
    cam = view.GetActiveCamera()
    cam.SetFocalPoint(centre)
    cam.SetPosition(centre[0], centre[1] - 10.0, centre[2])
    cam.SetViewUp(0.0, 0.0, 1.0)
    aspect = view.ViewSize[0] / view.ViewSize[1]
    if name == "front":
        view.CameraParallelProjection = 1
        # room for the caption above and the colour bars below the bed
        cam.SetParallelScale(0.5 * max(hi[2] - lo[2], (hi[0] - lo[0]) / aspect) * 1.3)
        view.CameraParallelScale = cam.GetParallelScale()
        return
    view.CameraParallelProjection = 0
    cam.Elevation(22.0)
    cam.Azimuth(-30.0)
    view.ResetCamera(lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], False)
    cam.Zoom(1.5)


def draw(a, out, report, parts, fem, t, t_ref, y_cut, words):
    view = pv.CreateView("RenderView")
    view.ViewSize = list(a.size)
    view.UseColorPaletteForBackground = 0
    view.Background = [1.0, 1.0, 1.0]
    view.OrientationAxesVisibility = 1
    view.ViewTime = t
    rocks, shown, total = cut_rocks(parts, t, t_ref, y_cut, a.field)
    show_rocks(view, rocks, a.field)
    sleeper = show_sleeper(view, fem, y_cut, t)
    sleeper.UpdatePipeline(t)
    b = sleeper.GetDataInformation().GetBounds()
    rocks.UpdatePipeline(t)
    r = rocks.GetDataInformation().GetBounds()
    show_walls(view, out, report, b[5] + 0.05)
    pressures = cell_pressures(out, report.get("cells", {}).get("cells", []), t)
    caption(view, f"{run_name(out)}: {words}\n"
            f"bed cut open at y = {y_cut:.3f} m, the sleeper's centre line: the {shown} of "
            f"{total} rocks whose centre lies behind it, the sleeper's half behind it\n"
            "pressure cells (magenta), top-face pressure (kPa): " +
            ", ".join(f"{n} {round(p)}" for n, p in pressures))
    prefix = a.png or os.path.join(out, "sleeper_cutaway")
    written = []
    pv.Render(view)  # paraview.simple resets the camera on a view's first render: done here
    for name in ("front", "oblique"):
        aim(view, [r[0], y_cut, r[4]], [r[1], r[3], b[5]], name)
        pv.Render(view)
        path = f"{prefix}_{name}.png"
        part = f"{prefix}_{name}.part.png"  # renamed when whole: no half-written picture
        if not pv.SaveScreenshot(part, view, ImageResolution=list(a.size)):
            raise InputError(f"{part}: ParaView could not write the picture")
        os.replace(part, path)
        written.append(path)
    print(f"sleeper_cutaway.py: the picture at t = {t:.9g} s, the rocks' displacement from "
          f"t = {t_ref:.9g} s, {shown} of {total} rocks behind y = {y_cut:.9g} m; wrote "
          + ", ".join(written))
    pv.Delete(view)  # before the interpreter ends: its OpenGL context goes with the X display
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except InputError as e:
        print(f"sleeper_cutaway.py: {e}", file=sys.stderr)
        sys.exit(2)
