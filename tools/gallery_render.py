"""One gallery picture of a run's output folder: the structure (fem.xdmf) coloured by its
displacement, which is scaled up so that it shows, the particles (particles.xdmf: spheres as
spheres of their radius, rocks as their surfaces) and the walls (walls.xdmf, see-through), at
the run's last output time, seen from the front and a little above. Whatever of the three
the folder has is drawn. Run with ParaView's own Python (Debian: python3-paraview), which
needs an X server (xvfb-run gives it one); tools/gallery_pictures.py runs it for every scene:

usage: xvfb-run -a pvbatch tools/gallery_render.py OUT_DIR PICTURE.png [TITLE]
"""

import os
import sys

if __name__ == "__main__" and any(a in ("-h", "--help") for a in sys.argv[1:]):
    print(__doc__.strip())  # before ParaView is needed: --help answers with any Python
    sys.exit(0)

from demfem_post.needs import need_or_exit  # noqa: E402 (after the --help answer)

pv = need_or_exit("gallery_render.py", "paraview.simple", "python3-paraview", "pvbatch")

SIZE = [800, 450]
COLOURED = []  # displays coloured by the displacement: their scale is set at the time drawn


def last_time(reader):
    times = list(reader.TimestepValues) if reader.TimestepValues else []
    return times[-1] if times else 0.0


def bounds_of(source, time=None):
    if time is None:
        source.UpdatePipeline()
    else:
        source.UpdatePipeline(time)
    return source.GetDataInformation().GetBounds()


def show_structure(view, path, vector, time):
    """The structure coloured by `vector` (a point array) at `time`, deformed by it."""
    fem = pv.OpenDataFile(path)
    b = bounds_of(fem, time)  # the vector's range at the time drawn
    size = max(b[1] - b[0], b[3] - b[2], b[5] - b[4])
    arrays = fem.PointData.keys()
    source = fem
    if vector in arrays:
        largest = fem.PointData[vector].GetRange(-1)[1]
        if largest > 0.0:  # the largest displacement drawn as 5 % of the structure's size
            source = pv.WarpByVector(Input=fem, Vectors=["POINTS", vector],
                                     ScaleFactor=0.05 * size / largest)
    shown = pv.Show(source, view)
    if vector in arrays:
        pv.ColorBy(shown, ("POINTS", vector, "Magnitude"))
        COLOURED.append((shown, vector))
    return source


def show_particles(view, path):
    particles = pv.OpenDataFile(path)
    particles.UpdatePipeline()
    info = particles.GetDataInformation()
    # Spheres: one vertex cell per particle (cells = points); rocks add their triangles (two
    # per surface vertex or so), so their snapshot has more cells than points.
    rocks = info.GetNumberOfCells() > info.GetNumberOfPoints()
    if rocks:  # rocks: their triangle surfaces are in the data set
        shown = pv.Show(particles, view)
    else:
        spheres = pv.Glyph(Input=particles, GlyphType="Sphere")
        spheres.ScaleArray = ["POINTS", "radius"]
        spheres.ScaleFactor = 2.0  # the sphere source has radius 0.5
        spheres.GlyphMode = "All Points"
        shown = pv.Show(spheres, view)
    pv.ColorBy(shown, None)
    shown.AmbientColor = shown.DiffuseColor = [0.80, 0.62, 0.35]
    return particles


def show_walls(view, path):
    walls = pv.OpenDataFile(path)
    shown = pv.Show(walls, view)
    pv.ColorBy(shown, None)
    shown.AmbientColor = shown.DiffuseColor = [0.55, 0.55, 0.6]
    shown.Opacity = 0.25
    return walls


def main(out_dir, png, title=None):
    view = pv.CreateView("RenderView")
    view.ViewSize = SIZE
    view.UseColorPaletteForBackground = 0
    view.Background = [1.0, 1.0, 1.0]
    view.OrientationAxesVisibility = 1
    shown, time, label = {}, None, "t = {:g} s"
    modes = os.path.join(out_dir, "fem_modes.xdmf")
    if os.path.isfile(modes):  # a modal analysis: its first mode (the series' "time" 1)
        time, label = 1.0, "mode {:g}"
        shown["fem.xdmf"] = show_structure(view, modes, "mode_shape", time)
    for name, show in (("fem.xdmf", show_structure), ("particles.xdmf", show_particles),
                       ("walls.xdmf", show_walls)):
        path = os.path.join(out_dir, name)
        if not os.path.isfile(path):
            continue
        if name == "fem.xdmf":
            shown[name] = show_structure(view, path, "displacement", last_time(pv.OpenDataFile(path)))
        else:
            shown[name] = show(view, path)
    if not shown:
        sys.exit(f"gallery_render.py: {out_dir} holds none of fem.xdmf, fem_modes.xdmf, "
                 "particles.xdmf, walls.xdmf")
    if time is None:
        time = max(last_time(r) for r in pv.GetSources().values() if hasattr(r, "TimestepValues"))
    scene = pv.GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    scene.AnimationTime = time
    view.ViewTime = time
    pv.Render(view)  # the displays at the time drawn, before their colour scale is set
    for display, vector in COLOURED:
        display.RescaleTransferFunctionToDataRange(False, True)
        display.SetScalarBarVisibility(view, True)
        bar = pv.GetScalarBar(pv.GetColorTransferFunction(vector), view)
        bar.Title = "displacement [m]" if vector == "displacement" else vector.replace("_", " ")
        bar.ComponentTitle = ""
        bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]
    # The camera frames the structure and the particles; the walls (a floor may be far larger)
    # only when there is nothing else.
    framed = [shown[n] for n in ("fem.xdmf", "particles.xdmf") if n in shown] or list(shown.values())
    bounds = [b for b in (bounds_of(s, time) for s in framed) if b[0] <= b[1]]
    if title:
        text = pv.Text(Text=f"{title}   ({label.format(time)})")
        shown = pv.Show(text, view)
        shown.FontSize = 13
        shown.Color = [0.0, 0.0, 0.0]
        shown.WindowLocation = "Upper Left Corner"
    view.CameraPosition = [0.0, -1.0, 0.45]
    view.CameraFocalPoint = [0.0, 0.0, 0.0]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    if bounds:
        box = [min(b[0] for b in bounds), max(b[1] for b in bounds), min(b[2] for b in bounds),
               max(b[3] for b in bounds), min(b[4] for b in bounds), max(b[5] for b in bounds)]
        view.ResetCamera(*box)
    else:
        view.ResetCamera()
    pv.Render(view)
    pv.SaveScreenshot(png, view, ImageResolution=SIZE)
    print(f"wrote {png} ({label.format(time)})")


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    main(*sys.argv[1:])
