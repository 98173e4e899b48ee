"""The first tutorial's ParaView picture: the beam coloured by its displacement, scaled up
100,000 times, with the spheres on it, at the run's last output time. Written for ParaView's
own Python (Debian: python3-paraview); no display needed:

    pvbatch docs/tutorials/beam_picture.py out/beam_dynamic_jit beam.png
"""

import os
import sys

from paraview import simple as pv

out_dir, png = sys.argv[1], sys.argv[2]
fem = pv.OpenDataFile(os.path.join(out_dir, "fem.xdmf"))
particles = pv.OpenDataFile(os.path.join(out_dir, "particles.xdmf"))
scene = pv.GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
scene.AnimationTime = fem.TimestepValues[-1]

view = pv.CreateView("RenderView")
view.ViewSize = [1200, 500]
view.UseColorPaletteForBackground = 0
view.Background = [1.0, 1.0, 1.0]
view.OrientationAxesVisibility = 0

warped = pv.WarpByVector(Input=fem, Vectors=["POINTS", "displacement"], ScaleFactor=1e5)
beam = pv.Show(warped, view)
pv.ColorBy(beam, ("POINTS", "displacement", "Magnitude"))
beam.SetScalarBarVisibility(view, True)
bar = pv.GetScalarBar(pv.GetColorTransferFunction("displacement"), view)
bar.Title = "displacement [m]"
bar.TitleColor = bar.LabelColor = [0.0, 0.0, 0.0]

spheres = pv.Glyph(Input=particles, GlyphType="Sphere")
spheres.ScaleArray = ["POINTS", "radius"]
spheres.ScaleFactor = 2.0  # the sphere source has radius 0.5: a diameter of 2 r
spheres.GlyphMode = "All Points"
shown = pv.Show(spheres, view)
pv.ColorBy(shown, None)
shown.AmbientColor = shown.DiffuseColor = [0.75, 0.75, 0.75]
shown.Opacity = 0.35

view.CameraPosition = [0.5, -0.75, 0.3]
view.CameraFocalPoint = [0.5, 0.05, 0.03]
view.CameraViewUp = [0.0, 0.0, 1.0]
pv.Render(view)
pv.SaveScreenshot(png, view, ImageResolution=[1200, 500])
print(f"wrote {png} (t = {scene.AnimationTime:g} s)")
