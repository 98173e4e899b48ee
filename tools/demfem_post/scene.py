"""A run's scene as the run saw it: the TOML file read with tomllib, with `KEY=VALUE`
overrides applied by the sweep's own reading of `demfem run --set` (tools/sweep/scene_keys.py),
so that a report of a run made with --set reads the values that run used."""

import json
import os
import tomllib

from sweep import scene_keys


def load_scene(scene_path, overrides=()):
    """The scene as tomllib reads it, with `KEY=VALUE` overrides applied as --set does.
    ValueError naming the scene and the override when one is malformed or names no key."""
    with open(scene_path, "rb") as f:
        sc = tomllib.load(f)
    for o in overrides:
        key, eq, text = o.partition("=")
        if not eq:
            raise ValueError(f"--set {o}: expected KEY=VALUE")
        try:
            value = tomllib.loads("v = " + text)["v"]
            scene_keys.assign(sc, key.strip(), value)
        except (tomllib.TOMLDecodeError, scene_keys.KeyError_) as e:
            raise ValueError(f"{scene_path}: --set {o}: {e}") from None
    return sc


def run_overrides(output_dir):
    """The --set overrides the run recorded in OUTPUT_DIR/run.json (none without one)."""
    path = os.path.join(output_dir, "run.json")
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(json.load(f).get("overrides", []))
