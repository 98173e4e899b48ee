"""A run's output folder: its run record (run.json), its scene, its CSV series, its fields
(XDMF + HDF5) and the reports the [[post]] tools wrote (<tool>_report.json), as
`demfem_post.open(path)` gives it."""

import glob
import json
import os

from .fields import FieldSeries
from .scene import load_scene
from .table import read_csv


class Run:
    """The output folder of one `demfem run` (docs/postprocessing.md)."""

    def __init__(self, path):
        self.path = os.path.abspath(str(path))
        if not os.path.isdir(self.path):
            raise FileNotFoundError(f"{path}: no such output folder")
        self._tables = {}
        self._fields = {}

    def __repr__(self):
        return f"demfem_post.open({self.path!r})"

    def file(self, name):
        """The path of `name` in the folder (FileNotFoundError naming it when absent)."""
        p = os.path.join(self.path, name)
        if not os.path.exists(p):
            raise FileNotFoundError(f"{p}: no such file")
        return p

    def _json(self, name):
        with open(self.file(name)) as f:
            return json.load(f)

    # --- the run record and the scene -----------------------------------------------------
    @property
    def info(self):
        """run.json as a dict: status, exit_code, scene, overrides, time_reached, ...
        (docs/reliability.md, "Run record")."""
        return self._json("run.json")

    @property
    def status(self):
        """'completed', 'failed', 'interrupted' or 'running' (from run.json)."""
        return self.info["status"]

    @property
    def exit_description(self):
        """The run's exit status in words as the sweep writes it, e.g. 'exit 3 (blow-up)'
        (names from the C++ exit-status header, through tools/sweep)."""
        from sweep.member import describe_exit
        return describe_exit(self.info.get("exit_code", 0))

    def scene(self, overrides=()):
        """The run's scene (run.json's `scene`) read with tomllib, with the run's recorded
        --set overrides and then `overrides` applied."""
        info = self.info
        return load_scene(info["scene"], list(info.get("overrides", [])) + list(overrides))

    # --- series ----------------------------------------------------------------------------
    def series(self, name):
        """The CSV series `name` (with or without .csv: 'coupling', 'sensor_outflow',
        'fem_monitor', 'fem_series', 'beam_check', 'timing') as a Table of numpy arrays."""
        stem = name[:-4] if name.endswith(".csv") else name
        if stem not in self._tables:
            self._tables[stem] = read_csv(self.file(stem + ".csv"))
        return self._tables[stem]

    def series_names(self):
        """Stems of every CSV series in the folder, sorted."""
        return sorted(os.path.basename(p)[:-4] for p in glob.glob(os.path.join(self.path, "*.csv")))

    @property
    def coupling(self):
        """coupling.csv: one row per coupling step (time, interface force, drift, ...)."""
        return self.series("coupling")

    @property
    def monitor(self):
        """fem_monitor.csv: the FEM probes' displacements and the interface force."""
        return self.series("fem_monitor")

    @property
    def fem_series(self):
        """fem_series.csv: the FEM's global series (energies, largest strain, ...)."""
        return self.series("fem_series")

    @property
    def beam_check(self):
        """beam_check.csv: the coupled against the pure-FEM deflection ([coupling.beam_check])."""
        return self.series("beam_check")

    def sensor(self, name):
        """sensor_<name>.csv of the DEM sensor `name` ([[dem.sensors]])."""
        return self.series("sensor_" + name)

    @property
    def sensors(self):
        """{name: Table} of every DEM sensor's series in the folder."""
        return {s[len("sensor_"):]: self.series(s) for s in self.series_names()
                if s.startswith("sensor_")}

    # --- fields (XDMF + HDF5) ----------------------------------------------------------------
    def fields(self, name):
        """The snapshots of `name`.xdmf ('particles', 'walls', 'fem', 'coupling', 'fem_modes',
        ...) as a FieldSeries: .times, .at(time), .snapshot(i)."""
        stem = name[:-5] if name.endswith(".xdmf") else name
        if stem not in self._fields:
            self._fields[stem] = FieldSeries(self.file(stem + ".xdmf"))
        return self._fields[stem]

    def particles(self, time):
        """The particles at the snapshot nearest to `time` (s): a Field of their centres
        (points; data radius, mass, velocity, id, ...) whose `shapes` is the Field of the
        rocks' triangle surfaces when the run has polyhedra, else None."""
        snap = self.fields("particles").at(time)
        if not isinstance(snap, dict):
            snap.shapes = None
            return snap
        centres = next(f for f in snap.values() if f.cell_type == "Polyvertex")
        centres.shapes = next((f for f in snap.values() if f.cell_type == "Triangle"), None)
        return centres

    def walls(self, time):
        """{wall name: Field} (triangles with their force data) at the snapshot nearest to
        `time` (s)."""
        snap = self.fields("walls").at(time)
        return snap if isinstance(snap, dict) else {snap.name: snap}

    def fem(self, time):
        """The FEM mesh at the snapshot nearest to `time` (s): nodes (points, m), elements
        (cells), nodal displacement and velocity, element stresses."""
        return self.fields("fem").at(time)

    # --- reports of the [[post]] tools ------------------------------------------------------
    def report(self, name):
        """The key figures a post tool wrote, <name>_report.json or <name>.json, as a dict
        (e.g. run.report('sheet'), run.report('sleeper'))."""
        for candidate in (f"{name}_report.json", f"{name}.json", name):
            if os.path.isfile(os.path.join(self.path, candidate)):
                return self._json(candidate)
        raise FileNotFoundError(f"{self.path}: no report '{name}' ({name}_report.json)")

    def plot(self, name, y=None, x=None, out=None, ax=None):
        """One-line plot of series `name`: run.plot('fem_monitor', 'lmp_uz', out='d.png')."""
        return self.series(name).plot(y, x, out, ax)

