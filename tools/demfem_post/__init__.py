"""demfem_post: the post-processing API of demfem's run folders (docs/postprocessing.md).

    import demfem_post
    run = demfem_post.open("out/beam_fixed_ci")
    run.info["status"]                    # run.json
    run.beam_check["coupled_deflection"]  # numpy arrays, one per CSV column
    run.monitor.frame()                   # a pandas DataFrame (when pandas is installed)
    run.report("sheet")                   # the key figures tools/sheet_report.py wrote
    run.fem(0.008)["displacement"]        # fields at a time (XDMF + HDF5): fem, particles, walls
    run.plot("coupling", "force_sum_z", out="force.png")

With tools/ on PYTHONPATH (the scripts in tools/ have it already). The CSV reader, the scene
reader (with --set overrides) and the exit-status names are the ones the tools use."""

import sys

if sys.version_info < (3, 11):  # tomllib, for the scenes
    raise ImportError(f"demfem_post needs Python 3.11 or newer (tomllib); {sys.executable} is "
                      f"Python {sys.version.split()[0]}: run with /usr/bin/python3 (Debian 12)")

from .fields import Field, FieldSeries  # noqa: E402
from .needs import MissingModule, need, tool_errors  # noqa: E402
from .run_folder import Run  # noqa: E402
from .scene import load_scene, run_overrides  # noqa: E402
from .table import Table, read_csv  # noqa: E402

__all__ = ["open", "Run", "Table", "Field", "FieldSeries", "read_csv", "load_scene",
           "run_overrides", "need", "MissingModule"]


def open(path):  # noqa: A001 -- the API's entry point, demfem_post.open(folder)
    """The run in output folder `path` (FileNotFoundError when it is not a folder)."""
    return Run(path)
