"""The CSV series of a run folder (coupling.csv, sensor_<name>.csv, fem_monitor.csv,
fem_series.csv, beam_check.csv): one reader for all of them and for the tools.

A Table is a mapping from column name to a numpy array (float64), in the file's column order;
`frame()` gives the same as a pandas DataFrame when pandas is installed, `lists()` the columns
as Python lists (the tools' pure-Python statistics, kept bit for bit)."""

import csv
import math
import os
from collections.abc import Mapping

from .needs import need


class Table(Mapping):
    """Columns of one CSV file: table["time"] is a numpy array; table.path, table.header."""

    def __init__(self, path, header, columns):
        self.path = str(path)
        self.header = list(header)
        self._columns = columns  # {name: list of float}, in header order
        self._arrays = {}

    def __getitem__(self, name):
        if name not in self._columns:
            raise KeyError(f"{self.path}: no column '{name}' (columns: {', '.join(self.header)})")
        if name not in self._arrays:
            np = need("numpy", "python3-numpy")
            self._arrays[name] = np.asarray(self._columns[name], dtype=float)
        return self._arrays[name]

    def __contains__(self, name):
        return name in self._columns

    def __iter__(self):
        return iter(self.header)

    def __len__(self):
        return len(self.header)

    def __repr__(self):
        return f"Table({self.path!r}, {self.rows} rows: {', '.join(self.header)})"

    @property
    def rows(self):
        """Number of data rows."""
        return len(self._columns[self.header[0]]) if self.header else 0

    def column(self, name):
        """One column as a Python list of floats (KeyError naming the file and its columns)."""
        if name not in self._columns:
            self[name]  # raises the KeyError that names the columns
        return self._columns[name]

    def lists(self):
        """{name: list of float}: the columns without numpy."""
        return dict(self._columns)

    def frame(self):
        """The table as a pandas DataFrame (needs pandas: Debian python3-pandas)."""
        pd = need("pandas", "python3-pandas")
        return pd.DataFrame({h: self[h] for h in self.header})

    def plot(self, y=None, x=None, out=None, ax=None):
        """One line per column of `y` (a name or a list; default: every column but x and
        step) against `x` (default: time, else the first column). Draws into `ax` (a
        matplotlib Axes) when given, else into a new figure, saved to `out` when given.
        Returns the Axes."""
        from .plots import plot_columns
        return plot_columns(self, y, x, out, ax)


def read_csv(path, incomplete_rows="skip", text_as_nan=False):
    """The CSV file at `path` as a Table. The header's names are stripped of blanks.

    incomplete_rows: "skip" leaves out rows whose field count differs from the header's (the
    last line of a run that was killed while writing it); "error" refuses them, naming the
    file and line. text_as_nan: a field that is not a number becomes NaN instead of an error.
    Errors: FileNotFoundError (no file), ValueError (no data rows, a bad row or field), each
    naming the file."""
    if incomplete_rows not in ("skip", "error"):
        raise ValueError(f"incomplete_rows must be 'skip' or 'error', not {incomplete_rows!r}")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2:
        raise ValueError(f"{path}: no data rows (only a header or empty)")
    header = [h.strip() for h in rows[0]]
    columns = {h: [] for h in header}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            if incomplete_rows == "skip":
                continue
            raise ValueError(f"{path}:{line}: {len(row)} fields, header has {len(header)}")
        for h, v in zip(header, row):
            try:
                columns[h].append(float(v))
            except ValueError:
                if not text_as_nan:
                    raise ValueError(f"{path}:{line}: column '{h}': '{v}' is not a number") \
                        from None
                columns[h].append(math.nan)
    return Table(path, header, columns)
