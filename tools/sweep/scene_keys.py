"""Scene keys as `demfem run --set KEY=VALUE` takes them (docs/scenes.md, "Overriding keys"):
parsing KEY, writing a Python value as TOML text, and applying an override to a scene read
with tomllib, with the same rules as scene::Document (a key of an existing table may be set
or added; tables and array entries are never created; a key under a prefix of the scene's
[dem.load] pass whose table or array entry the scene lacks is for the prepare scene only). The sweep uses this to know each
member's effective dem.threads, dem.backend and checkpoint.directory, and to refuse a
parameter key that the C++ reader would refuse, before any member starts."""

import json
import math
import re

_SEGMENT = re.compile(r"([A-Za-z0-9_-]+)((?:\[[0-9]{1,9}\])*)")


class KeyError_(ValueError):
    """A key that is malformed or does not exist in the scene."""


def parse_key(key):
    """'dem.pairs[0].friction' -> [('dem', []), ('pairs', [0]), ('friction', [])]."""
    steps = []
    for part in key.split("."):
        m = _SEGMENT.fullmatch(part)
        if not m:
            raise KeyError_(f"'{key}' is not a dotted scene key (segments of letters, digits, _ "
                            "and -, each with optional [index]), e.g. dem.pairs[0].friction")
        steps.append((m.group(1), [int(i) for i in re.findall(r"\[([0-9]+)\]", m.group(2))]))
    return steps


def toml_value(v):
    """A Python value (from tomllib) as TOML text that reads back as the same value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)  # shortest text that reads back as the same double
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string: same escapes
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"{type(v).__name__} cannot be a scene value")


def _toml_key(k):
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def get(scene, key, default=None):
    """The value of `key` in a tomllib scene, or `default` when any part is missing."""
    cur = scene
    for name, indices in parse_key(key):
        if not isinstance(cur, dict) or name not in cur:
            return default
        cur = cur[name]
        for i in indices:
            if not isinstance(cur, list) or i >= len(cur):
                return default
            cur = cur[i]
    return cur


def under(key, prefix):
    """Whether `key` is `prefix` or lies below it (Override::under)."""
    return key.startswith(prefix) and (len(key) == len(prefix) or key[len(prefix)] in ".[")


_MISSING = object()


def _target_exists(scene, key):
    """Whether the tables and array entries `key` walks through exist (its last key may be
    new: assign adds it)."""
    steps = parse_key(key)
    if steps[-1][1]:  # ends in an array entry: that entry must exist
        return get(scene, key, _MISSING) is not _MISSING
    holder = get(scene, key.rsplit(".", 1)[0], _MISSING) if len(steps) > 1 else scene
    return isinstance(holder, dict)


def assign(scene, key, value):
    """Sets `key` of the tomllib scene dict in place, as scene::Document does for --set;
    raises KeyError_ with the same reasons as the C++ reader. A key under a prefix of the
    scene's [dem.load] pass that this scene has no place for is left to the prepare scene
    (returns False); otherwise returns True."""
    steps = parse_key(key)
    passed = get(scene, "dem.load.pass", [])
    if (isinstance(passed, list) and any(isinstance(p, str) and under(key, p) for p in passed)
            and not _target_exists(scene, key)):
        return False
    cur = scene
    walked = ""
    for s, (name, indices) in enumerate(steps):
        last = s + 1 == len(steps)
        if not isinstance(cur, dict):
            raise KeyError_(f"'{walked}' is not a table, it has no key '{name}'")
        here = f"{walked}.{name}" if walked else name
        if last and not indices:
            cur[name] = value
            return True
        if name not in cur:
            kind = "array" if indices else "table"
            raise KeyError_(f"the scene has no {kind} '{here}' (an override sets or adds a key of "
                            "an existing table; it does not create tables or array entries)")
        node = cur[name]
        walked = here
        for j, i in enumerate(indices):
            if not isinstance(node, list):
                raise KeyError_(f"'{walked}' is not an array, it has no entry [{i}]")
            if i >= len(node):
                raise KeyError_(f"the scene has no '{walked}[{i}]' ('{walked}' has {len(node)} "
                                "entries)")
            walked += f"[{i}]"
            if last and j + 1 == len(indices):
                node[i] = value
                return True
            node = node[i]
        cur = node
