"""Fields of a run at a time, from its XDMF files and the HDF5 files they point at: the
particles (points with radius, velocity, ...; rocks as triangle surfaces beside them), the
walls (a triangle surface each), the FEM (nodes, elements, displacement, stresses) and the
coupling interface. Any of demfem's XDMF files is read the same way: a temporal collection of
snapshots, each one grid or a spatial collection of grids (walls; particles with polyhedra)."""

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping

from .hdf5 import read_dataset


class Field:
    """One grid of one snapshot: `points` (n, 3), `cells` (m, k) with `cell_type` ('Triangle',
    'Hexahedron', 'Polyvertex', ...), and the data by name, `point_data` and `cell_data`,
    read from the HDF5 files when first asked for."""

    def __init__(self, folder, grid, time):
        self.name = grid.get("Name")
        self.time = time
        self._folder = folder
        topology = grid.find("Topology")
        self.cell_type = topology.get("TopologyType")
        self._items = {"points": grid.find("Geometry/DataItem"),
                       "cells": topology.find("DataItem")}
        self._point_items, self._cell_items = {}, {}
        for a in grid.findall("Attribute"):
            where = self._point_items if a.get("Center") == "Node" else self._cell_items
            where[a.get("Name")] = a.find("DataItem")
        self._cache = {}

    def __repr__(self):
        return (f"Field({self.name!r}, t = {self.time:g} s, {self.cell_type}; point data: "
                f"{', '.join(self._point_items)}; cell data: {', '.join(self._cell_items)})")

    def _read(self, item):
        key = id(item)
        if key not in self._cache:
            h5, _, dataset = item.text.strip().partition(":")
            self._cache[key] = read_dataset(os.path.join(self._folder, h5), dataset)
        return self._cache[key]

    @property
    def points(self):
        """Point coordinates (n, 3), m."""
        return self._read(self._items["points"])

    @property
    def cells(self):
        """Cells as point indices (m, k); (n, 1) for particles (Polyvertex)."""
        return self._read(self._items["cells"])

    @property
    def point_data(self):
        """{name: array} of the data at the points (a read on first access of each)."""
        return _LazyData(self, self._point_items)

    @property
    def cell_data(self):
        """{name: array} of the data on the cells."""
        return _LazyData(self, self._cell_items)

    def __getitem__(self, name):
        """A point datum by name, else a cell datum (KeyError naming both lists)."""
        for items in (self._point_items, self._cell_items):
            if name in items:
                return self._read(items[name])
        raise KeyError(f"{self.name} at t = {self.time:g} s: no data '{name}' (points: "
                       f"{', '.join(self._point_items)}; cells: {', '.join(self._cell_items)})")


class _LazyData(Mapping):
    """{name: array} of a Field's point or cell data, each read when first asked for."""

    def __init__(self, field, items):
        self._field, self._items = field, items

    def __getitem__(self, name):
        if name not in self._items:
            raise KeyError(f"{self._field.name}: no data '{name}' ({', '.join(self._items)})")
        return self._field._read(self._items[name])

    def __iter__(self):
        return iter(self._items)

    def __len__(self):
        return len(self._items)


class FieldSeries:
    """The snapshots of one XDMF file: `times` (s) and `at(time)`, `snapshot(i)`."""

    def __init__(self, path):
        self.path = str(path)
        if not os.path.isfile(self.path):
            raise FileNotFoundError(f"{self.path}: no such file")
        try:
            root = ET.parse(self.path).getroot()
        except ET.ParseError as e:
            raise ValueError(f"{self.path}: not XDMF ({e})") from None
        temporal = root.find("Domain/Grid")
        if temporal is None or temporal.get("CollectionType") != "Temporal":
            raise ValueError(f"{self.path}: no temporal collection of grids")
        self._folder = os.path.dirname(os.path.abspath(self.path))
        self._snapshots = list(temporal.findall("Grid"))
        self.times = [float(g.find("Time").get("Value")) for g in self._snapshots]

    def __len__(self):
        return len(self._snapshots)

    def __repr__(self):
        return f"FieldSeries({self.path!r}, {len(self)} snapshots)"

    def snapshot(self, i):
        """Snapshot i: a Field, or for a spatial collection {grid name: Field}."""
        g = self._snapshots[i]
        t = self.times[i]
        if g.get("GridType") == "Collection":
            return {c.get("Name"): Field(self._folder, c, t) for c in g.findall("Grid")}
        return Field(self._folder, g, t)

    def index(self, time):
        """Index of the snapshot nearest to `time` (ValueError when there are none)."""
        if not self.times:
            raise ValueError(f"{self.path}: no snapshots")
        return min(range(len(self.times)), key=lambda i: abs(self.times[i] - time))

    def at(self, time):
        """The snapshot nearest to `time` (s); its `time` says which it is."""
        return self.snapshot(self.index(time))
