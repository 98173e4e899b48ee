"""Reading a sweep file (TOML) strictly: every key is checked for its type and range, an
unknown key is an error, and every message names the file, the line and the key, as the
scene reader does (docs/sweeps.md lists the keys)."""

import copy
import math
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from sweep import scene_keys
from sweep.safe_text import control_character, sbatch_option_problem, slurm_value_problem
from sweep.stages import check_override, read_stages
from sweep.toml_lines import key_lines

REQUIRED = object()
_NAME = re.compile(r"[A-Za-z0-9_.-]+")
_PARAMETER_NAME = re.compile(r"[A-Za-z0-9_.\[\]-]+")  # a scene key is a good default
REDUCTIONS = ("final", "max", "min", "mean", "series")
# Members of one sweep (settings x repetitions): execution.max_members, by default
# MAX_MEMBERS_DEFAULT, at most MAX_MEMBERS_LIMIT (docs/sweeps.md, "How many members").
MAX_MEMBERS_DEFAULT = 10000
MAX_MEMBERS_LIMIT = 1000000
# Keys the sweep sets for every member itself (--output-dir gives each its folder).
SWEEP_OWN_KEYS = ("run.output_dir",)


class SweepError(Exception):
    """Bad input (sweep file, scene, command line): exit status 2."""


# The largest sweep file or scene read, as the C++ scene reader's io::kSceneFileLimit.
FILE_LIMIT = 16 << 20


def read_text(path, what):
    """The UTF-8 text of the regular file `path` (at most FILE_LIMIT bytes); SweepError
    naming the file and `what` it should be otherwise. A FIFO or a device is refused before
    it is opened (a FIFO would block, /dev/zero never end)."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise SweepError(f"{path}: cannot read {what} ({e.strerror})")
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise SweepError(f"{path}: is {kind}; expected {what}")
    try:
        with open(path, "rb") as f:
            data = f.read(FILE_LIMIT + 1)
    except OSError as e:
        raise SweepError(f"{path}: cannot read {what} ({e.strerror})")
    if len(data) > FILE_LIMIT:
        raise SweepError(f"{path}: is larger than {FILE_LIMIT >> 20} MiB, the limit for {what}")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SweepError(f"{path}: is not UTF-8 text (byte {e.start}); expected {what}")


def _show(path):
    out = ""
    for p in path:
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            q = p if re.fullmatch(r"[A-Za-z0-9_-]+", p) else f'"{p}"'
            out += ("." if out else "") + q
    return out


class Table:
    """One table of the sweep file; remembers which keys were read so finish() can refuse
    the others."""

    def __init__(self, data, path, file, lines):
        self.data, self.path, self.file, self.lines = data, path, file, lines
        self.used = set()

    def where(self, key=None):
        path = self.path + ((key,) if key is not None else ())
        # The key's own line, else its nearest table's (a key inside an inline table or a
        # multi-line array has no line of its own: the line where that value starts).
        line = next((self.lines[path[:n]] for n in range(len(path), 0, -1)
                     if path[:n] in self.lines), None)
        loc = f"{self.file}:{line}" if line else str(self.file)
        return f"{loc}: key '{_show(path)}'" if path else loc

    def fail(self, key, message):
        raise SweepError(f"{self.where(key)}: {message}")

    def has(self, key):
        return key in self.data

    def _get(self, key, default):
        self.used.add(key)
        if key not in self.data:
            if default is REQUIRED:
                self.fail(key, "is required but missing")
            return default, False
        return self.data[key], True

    def number(self, key, default=REQUIRED, lo=-math.inf, hi=math.inf, lo_open=False):
        v, found = self._get(key, default)
        if not found:
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(key, f"must be a number, found {_type(v)}")
        v = float(v)
        if not math.isfinite(v):
            self.fail(key, f"must be finite, found {v}")
        if v < lo or v > hi or (lo_open and v == lo):
            self.fail(key, f"is {v:g}, outside the accepted range {_range(lo, hi, lo_open)}")
        return v

    def integer(self, key, default=REQUIRED, lo=-(2**63), hi=2**63 - 1):
        v, found = self._get(key, default)
        if not found:
            return v
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(key, f"must be an integer, found {_type(v)}")
        if v < lo or v > hi:
            self.fail(key, f"is {v}, outside the accepted range [{lo}, {hi}]")
        return v

    def boolean(self, key, default=REQUIRED):
        v, found = self._get(key, default)
        if found and not isinstance(v, bool):
            self.fail(key, f"must be true or false, found {_type(v)}")
        return v

    def string(self, key, default=REQUIRED, choices=None, allow_empty=False):
        v, found = self._get(key, default)
        if not found:
            return v
        if not isinstance(v, str):
            self.fail(key, f"must be a string, found {_type(v)}")
        self._no_control(key, v)
        if not allow_empty and not v:
            self.fail(key, "must not be empty")
        if choices and v not in choices:
            self.fail(key, f'is "{v}", accepted: ' + ", ".join(f'"{c}"' for c in choices))
        return v

    def strings(self, key, default=REQUIRED):
        v, found = self._get(key, default)
        if not found:
            return v
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(key, f"must be an array of strings, found {_type(v)}")
        for i, x in enumerate(v):
            self._no_control(key, x, f"entry {i} ")
        return list(v)

    def _no_control(self, key, text, which=""):
        # Names, paths and options end up in file names, logs and job scripts, where a
        # newline would start a new line (safe_text).
        bad = control_character(text)
        if bad:
            self.fail(key, f"{which}{bad}: control characters are not accepted in the values "
                      "of a sweep file (they are written into file names and job scripts)")

    def table(self, key):
        v, found = self._get(key, None)
        if not found:
            return None
        if not isinstance(v, dict):
            self.fail(key, f"must be a table, found {_type(v)}")
        return Table(v, self.path + (key,), self.file, self.lines)

    def tables(self, key):
        v, found = self._get(key, None)
        if not found:
            return []
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            self.fail(key, f"must be an array of tables ([[{_show(self.path + (key,))}]])")
        return [Table(x, self.path + (key, i), self.file, self.lines) for i, x in enumerate(v)]

    def finish(self):
        for k in self.data:
            if k not in self.used:
                self.fail(k, "is not a known key here (misspelt, or not accepted in this "
                          "section; docs/sweeps.md lists the keys)")


def _type(v):
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "an array", dict: "a table"}.get(type(v), "a date/time")


def _range(lo, hi, lo_open):
    if hi == math.inf:
        return f"{'>' if lo_open else '>='} {lo:g}"
    return f"[{lo:g}, {hi:g}]"


@dataclass
class Parameter:
    name: str
    unit: str
    keys: list          # scene keys, zipped
    values: list        # values[k] = the list of values of keys[k]

    @property
    def count(self):
        return len(self.values[0])


@dataclass
class Quantity:
    name: str
    file: str           # relative to the member's output folder
    column: str
    time_column: str
    unit: str
    kind: str           # "at" or one of REDUCTIONS
    at: float = math.nan
    method: str = "linear"
    window: tuple = (-math.inf, math.inf)
    last: float = math.nan  # > 0: the window is the member's last `last` seconds instead
    relative_to: float = math.nan  # a time: the column's value then is subtracted first
    where: str = ""     # "file:line: key 'quantity[i]'" for messages at collection
    stage: str = ""     # the stage whose folder holds `file` ("" = the member's folder)


@dataclass
class Repetitions:
    count: int
    seeds: list
    key: str


@dataclass
class Execution:
    threads: int = 1
    max_retries: int = 2
    timeout: float = 0.0
    jobs: int = 0
    args: list = field(default_factory=list)
    max_members: int = MAX_MEMBERS_DEFAULT
    beds: str = "member"  # where [dem.load] scene beds are prepared: "member" or "shared"


@dataclass
class SlurmOptions:
    partition: str = ""
    time: str = ""
    account: str = ""
    qos: str = ""
    mem: str = ""
    max_concurrent: int = 0
    options: list = field(default_factory=list)


@dataclass
class Spec:
    file: Path
    name: str
    scene: Path
    scene_data: dict
    output_dir: Path
    parameters: list
    repetitions: Repetitions
    execution: Execution
    slurm: SlurmOptions
    quantities: list
    stages: list = field(default_factory=list)   # [stages.Stage]; empty: one run per member


def _scene_value_ok(v):
    if isinstance(v, float):
        return math.isfinite(v)
    if isinstance(v, list):
        return all(_scene_value_ok(x) for x in v)
    if isinstance(v, dict):
        return all(_scene_value_ok(x) for x in v.values())
    return isinstance(v, (bool, int, str))


def read_sweep_file(path):
    """Reads and checks a sweep file; raises SweepError (exit 2) naming file, line and key."""
    path = Path(path)
    text = read_text(path, "a sweep file (TOML)")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SweepError(f"{path}: TOML syntax error: {e}")
    root = Table(data, (), path, key_lines(text))

    sw = root.table("sweep")
    if sw is None:
        root.fail("sweep", "is required but missing (the [sweep] table names the base scene)")
    name = sw.string("name", path.stem)
    if not _NAME.fullmatch(name):
        sw.fail("name", "must be letters, digits, '_', '.' or '-' (it names folders and jobs)")
    output_dir = Path(sw.string("output_dir", str(Path("out") / "sweeps" / name)))
    stages = read_stages(root, path, _read_scene)
    if stages:
        if sw.has("scene"):
            sw.fail("scene", "is not given with [[stage]]: each stage names its scene")
        # The last stage is the member's result: quantities are taken from it by default.
        scene, scene_data = stages[-1].scene, stages[-1].scene_data
    else:
        scene = Path(sw.string("scene"))
        scene = Path(os.path.abspath(scene if scene.is_absolute() else path.parent / scene))
        scene_data = _read_scene(sw, "scene", scene)
    sw.finish()

    parameters, seen_keys = _read_parameters(root, scene, scene_data, stages)
    rep = _read_repetitions(root, scene, scene_data, stages, seen_keys)
    ex = _read_execution(root)
    sl = _read_slurm(root)
    quantities = _read_quantities(root, parameters, stages)
    root.finish()
    return Spec(path, name, scene, scene_data, output_dir, parameters, rep, ex, sl, quantities,
                stages)


def _read_scene(table, key, scene):
    """The TOML data of the scene that `table.key` names (SweepError naming that key)."""
    try:
        return tomllib.loads(read_text(scene, "a scene file (TOML)"))
    except SweepError as e:
        table.fail(key, f"cannot read the scene: {e}")
    except tomllib.TOMLDecodeError as e:
        table.fail(key, f"the scene {scene} is not valid TOML: {e}")


def _check_key(table, where, key, value, scene, scene_data, stages):
    """`key`, a scene key that the sweep sets for every member (a parameter's; the
    repetitions' seed), against the scene, or the stages, it goes to; a problem is reported
    at `table.where`."""
    if stages:
        check_override(stages, key, value, lambda message: table.fail(where, message))
        return
    try:
        scene_keys.assign(copy.deepcopy(scene_data), key, value)
    except scene_keys.KeyError_ as e:
        table.fail(where, f"{e} (scene {scene})")


def _read_parameters(root, scene, scene_data, stages):
    parameters = []
    seen_keys = {}
    for t in root.tables("parameter"):
        keys_t = t.table("keys")
        if keys_t is None or not keys_t.data:
            t.fail("keys", "is required: a table of scene keys, each with an array of values")
        keys, values = [], []
        for k, v in keys_t.data.items():
            keys_t.used.add(k)
            if not isinstance(v, list) or not v:
                keys_t.fail(k, "must be a non-empty array of values")
            for x in v:
                if not _scene_value_ok(x):
                    keys_t.fail(k, f"has a value that is not a finite scene value: {x!r}")
            if values and len(v) != len(values[0]):
                keys_t.fail(k, f"has {len(v)} values, '{keys[0]}' of the same [[parameter]] has "
                            f"{len(values[0])} (the keys of one parameter are zipped: equal "
                            "lengths)")
            if k in seen_keys:
                keys_t.fail(k, f"is already set by {seen_keys[k]}")
            if k in SWEEP_OWN_KEYS:
                keys_t.fail(k, "is set by the sweep itself: every member writes into its own "
                            "folder, <output_dir>/members/<member>")
            _check_key(keys_t, k, k, v[0], scene, scene_data, stages)
            seen_keys[k] = keys_t.where(k)
            keys.append(k)
            values.append(list(v))
        pname = t.string("name", keys[0])
        if not _PARAMETER_NAME.fullmatch(pname):
            t.fail("name", "must be letters, digits and '_.-[]' (it names a CSV column)")
        unit = t.string("unit", "", allow_empty=True)
        t.finish()
        parameters.append(Parameter(pname, unit, keys, values))
    return parameters, seen_keys


def _read_repetitions(root, scene, scene_data, stages, seen_keys):
    rt = root.table("repetitions")
    if rt is None:
        rep = Repetitions(1, [scene_keys.get(scene_data, "run.seed", 1)], "run.seed")
    else:
        count = rt.integer("count", 1, 1, 100000)
        key = rt.string("key", "run.seed")
        if rt.has("seeds"):
            seeds = rt.data["seeds"]
            rt.used.add("seeds")
            if (not isinstance(seeds, list) or
                    not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                            for s in seeds)):
                rt.fail("seeds", "must be an array of integers >= 0")
            if rt.has("count") and len(seeds) != count:
                rt.fail("seeds", f"has {len(seeds)} seeds, repetitions.count is {count}")
            if len(set(seeds)) != len(seeds):
                rt.fail("seeds", "has a seed twice (repetitions would be identical)")
            if rt.has("first_seed"):
                rt.fail("first_seed", "cannot be given with seeds")
            count = len(seeds)
            if count == 0:
                rt.fail("seeds", "must not be empty")
        else:
            first = rt.integer("first_seed", 1, 0, 2**63 - 1 - count)
            seeds = [first + i for i in range(count)]
        if key in seen_keys:
            rt.fail("key", f"'{key}' is also a parameter ({seen_keys[key]})")
        if key in SWEEP_OWN_KEYS:
            rt.fail("key", f"'{key}' is set by the sweep itself (each member's own folder)")
        _check_key(rt, "key", key, seeds[0], scene, scene_data, stages)
        rt.finish()
        rep = Repetitions(count, seeds, key)
    return rep


def _read_execution(root):
    ex = Execution()
    et = root.table("execution")
    if et is not None:
        ex.threads = et.integer("threads", 1, 1, 4096)
        ex.max_retries = et.integer("max_retries", 2, 0, 100)
        ex.timeout = et.number("timeout", 0.0, 0.0)
        ex.jobs = et.integer("jobs", 0, 0, 100000)
        ex.args = et.strings("args", [])
        ex.max_members = et.integer("max_members", MAX_MEMBERS_DEFAULT, 1, MAX_MEMBERS_LIMIT)
        ex.beds = et.string("beds", "member", choices=("member", "shared"))
        for a in ex.args:
            if a in ("--output-dir", "--resume", "--set", "--check", "--bin-dir") or \
                    a.startswith(("--output-dir=", "--resume=", "--set=")):
                et.fail("args", f"'{a}' is set by the sweep itself for each member")
        et.finish()
    return ex


def _read_slurm(root):
    sl = SlurmOptions()
    st = root.table("slurm")
    if st is not None:
        for k in ("partition", "time", "account", "qos", "mem"):
            setattr(sl, k, st.string(k, ""))
            bad = slurm_value_problem(k, getattr(sl, k))
            if bad:
                st.fail(k, bad)
        sl.max_concurrent = st.integer("max_concurrent", 0, 0, 1000000)
        sl.options = st.strings("options", [])
        for o in sl.options:
            bad = sbatch_option_problem(o)
            if bad:
                st.fail("options", bad)
        st.finish()
    return sl


def _read_quantities(root, parameters, stages):
    quantities = []
    names = {p.name for p in parameters}
    for t in root.tables("quantity"):
        qname = t.string("name")
        if not _NAME.fullmatch(qname):
            t.fail("name", "must be letters, digits, '_', '.' or '-' (it names a CSV column)")
        if qname in names or qname in ("member", "setting", "seed", "status", "attempts",
                                       "run_time"):
            t.fail("name", f"'{qname}' is already a column (a parameter, another quantity or "
                   "one of member, setting, seed, status, attempts, run_time)")
        names.add(qname)
        qfile = t.string("file")
        if Path(qfile).is_absolute() or ".." in Path(qfile).parts:
            t.fail("file", "must be a path inside the member's output folder (e.g. "
                   '"coupling.csv", "sensor_ke.csv")')
        q = Quantity(qname, qfile, t.string("column"), t.string("time_column", "time"),
                     t.string("unit", "", allow_empty=True), "", where=t.where())
        has_at, has_reduce = t.has("at"), t.has("reduce")
        if has_at == has_reduce:
            t.fail("at" if has_at else "reduce", "exactly one of 'at' (a time) and 'reduce' ("
                   + ", ".join(f'"{r}"' for r in REDUCTIONS) + ") must be given")
        if has_at:
            q.kind = "at"
            q.at = t.number("at")
            q.method = t.string("method", "linear", choices=("linear", "nearest"))
        else:
            q.kind = t.string("reduce", choices=REDUCTIONS)
            if t.has("method"):
                t.fail("method", "applies to 'at' only")
        if t.has("window"):
            if q.kind in ("at", "final"):
                t.fail("window", f"does not apply to {q.kind!r}")
            w = t.data["window"]
            t.used.add("window")
            if (not isinstance(w, list) or len(w) != 2 or
                    not all(isinstance(x, (int, float)) and not isinstance(x, bool) and
                            math.isfinite(x) for x in w) or not w[0] < w[1]):
                t.fail("window", "must be [t0, t1] in s with t0 < t1")
            q.window = (float(w[0]), float(w[1]))
        if t.has("last"):
            if q.kind in ("at", "final"):
                t.fail("last", f"does not apply to {q.kind!r}")
            if t.has("window"):
                t.fail("last", "exactly one of 'window' (fixed times) and 'last' (the member's "
                       "last seconds) may be given")
            q.last = t.number("last", lo=0.0, lo_open=True)
        if t.has("relative_to"):
            q.relative_to = t.number("relative_to")
        if stages:
            q.stage = t.string("stage", stages[-1].name,
                               choices=[s.name for s in stages])
        elif t.has("stage"):
            t.fail("stage", "needs [[stage]] tables (a sweep without them has one run per member)")
        t.finish()
        quantities.append(q)
    return quantities
