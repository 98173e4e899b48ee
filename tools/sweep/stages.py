"""Chained stages (docs/sweeps.md, "Chained stages"): a member that is a chain of demfem runs,
each stage a scene of its own that starts when the member's stage before it is done (a bed
prepared, then the load case on it). Which of the member's overrides a stage gets (`pass`),
the stage's own overrides (`set`) with `{STAGE}` standing for the folder of an earlier stage
of the same member, and the checks of both against the stage's scene."""

import copy
import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from sweep import scene_keys

_STAGE_NAME = re.compile(r"[A-Za-z0-9_-]+")
# `{NAME}` in a stage's set: the folder of the member's earlier stage NAME (absolute).
PLACEHOLDER = re.compile(r"\{([A-Za-z0-9_-]+)\}")


@dataclass
class Stage:
    name: str
    scene: Path
    scene_data: dict
    passes: list = None          # key prefixes of the member's overrides it gets; None = all
    sets: list = field(default_factory=list)   # "KEY=VALUE" with {STAGE} placeholders
    where: str = ""

    def receives(self, key):
        """Whether the member's override of `key` goes to this stage."""
        return self.passes is None or any(scene_keys.under(key, p) for p in self.passes)


def read_stages(root, sweep_path, read_scene):
    """The [[stage]] tables in order (empty: a member is one run of [sweep] scene). Each
    names a stage (a folder of the member), its scene, `pass` and `set`; a `set` entry's
    {NAME} must be an earlier stage. `read_scene(table, key, path)` reads a scene's TOML."""
    stages = []
    for t in root.tables("stage"):
        name = t.string("name")
        if not _STAGE_NAME.fullmatch(name) or name in ("members", "plots", "slurm"):
            t.fail("name", "must be letters, digits, '_' or '-' (it names the stage's folder "
                   "inside the member's), not 'members', 'plots' or 'slurm'")
        if any(s.name == name for s in stages):
            t.fail("name", f"'{name}' names two stages")
        scene = Path(t.string("scene"))
        scene = Path(os.path.abspath(scene if scene.is_absolute() else sweep_path.parent / scene))
        data = read_scene(t, "scene", scene)
        passes = t.strings("pass") if t.has("pass") else None
        sets = t.strings("set", [])
        stage = Stage(name, scene, data, passes, sets, t.where())
        for entry in sets:
            _check_set_entry(t, stage, entry, stages)
        t.finish()
        stages.append(stage)
    return stages


def _check_set_entry(t, stage, entry, earlier):
    if "=" not in entry:
        t.fail("set", f"entry '{entry}' is not KEY=VALUE (as for --set)")
    key, value = (x.strip() for x in entry.split("=", 1))
    for ref in PLACEHOLDER.findall(value):
        if not any(s.name == ref for s in earlier):
            t.fail("set", f"entry '{entry}': {{{ref}}} is not an earlier stage (it stands for "
                   "the folder of one of this member's stages before this one: " +
                   (", ".join(s.name for s in earlier) or "none") + ")")
    text = PLACEHOLDER.sub(lambda m: "/" + m.group(1), value)
    try:
        parsed = tomllib.loads("v = " + text)["v"]
    except tomllib.TOMLDecodeError:
        t.fail("set", f"entry '{entry}': the value is not a TOML value (strings need quotes)")
    if key == "run.output_dir":
        t.fail("set", "run.output_dir is set by the sweep itself: every stage writes into "
               "<member>/<stage>")
    try:
        scene_keys.assign(copy.deepcopy(stage.scene_data), key, parsed)
    except scene_keys.KeyError_ as e:
        t.fail("set", f"entry '{entry}': {e} (scene {stage.scene})")


def check_override(stages, key, value, fail):
    """A parameter's or the repetitions' key against every stage that gets it; one stage at
    least must (else the parameter would change nothing). `fail(message)` raises."""
    takers = [s for s in stages if s.receives(key)]
    if not takers:
        fail(f"'{key}' reaches no stage: no [[stage]] pass list covers it (" +
             "; ".join(f"{s.name}: {s.passes}" for s in stages) + ")")
    for s in takers:
        try:
            scene_keys.assign(copy.deepcopy(s.scene_data), key, value)
        except scene_keys.KeyError_ as e:
            fail(f"{e} (stage '{s.name}', scene {s.scene})")


def stage_overrides(stage, member_overrides, folders):
    """The overrides of one stage of a member: those of the member's that it gets, then its
    own `set` with {NAME} replaced by that stage's folder (`folders`: name -> absolute path)."""
    own = [o for o in member_overrides if stage.receives(o.split("=", 1)[0])]
    for entry in stage.sets:
        key, value = entry.split("=", 1)
        own.append(key.strip() + "=" + PLACEHOLDER.sub(
            lambda m: folders[m.group(1)].replace("\\", "\\\\").replace('"', '\\"'),
            value.strip()))
    return own


def refers_to_earlier_stage(override, stage):
    """Whether `override` is one of the stage's own entries that names an earlier stage's
    folder (its file does not exist before that stage has run: left out of the check)."""
    return any(PLACEHOLDER.search(e) and override.split("=", 1)[0] == e.split("=", 1)[0].strip()
               for e in stage.sets)
