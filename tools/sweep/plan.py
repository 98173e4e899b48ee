"""The members of a sweep: every setting (the Cartesian product of the parameters, each
parameter's keys zipped) times every repetition, with the overrides that make each one, its
thread count and whether it needs a GPU."""

import copy
import hashlib
import itertools
import os
from dataclasses import asdict, dataclass
from pathlib import Path

from sweep import scene_keys
from sweep.records import IDENTITY_FILE, read_json, write_json_atomic
from sweep.sweep_file import SweepError


@dataclass
class Member:
    index: int            # 0-based; also the Slurm array index
    id: str               # folder name, e.g. "s01_r02"
    setting: int
    repetition: int
    seed: int
    values: dict          # parameter name -> value of its first key
    overrides: list       # "KEY=VALUE" for demfem_run --set, in order
    threads: int          # CPU threads the member uses (its dem.threads)
    gpu: bool             # dem.backend = "cuda": one GPU
    checkpoints: str      # checkpoint folder relative to the member folder ("" = none)
    folder: str           # absolute


@dataclass
class Plan:
    name: str
    sweep_file: str
    scene: str
    scene_sha256: str
    output_dir: str
    demfem_run: str
    max_retries: int
    timeout: float
    args: list
    parameters: list      # [{"name", "unit", "keys", "values"}]
    members: list

    def to_json(self):
        d = asdict(self)
        return d

    @staticmethod
    def from_json(d):
        d = dict(d)
        d["members"] = [Member(**m) for m in d["members"]]
        return Plan(**d)


def _width(n):
    return max(2, len(str(max(n - 1, 0))))


def build_plan(spec, output_dir, demfem_run):
    scene_bytes = spec.scene.read_bytes()
    axes = [range(p.count) for p in spec.parameters]
    settings = list(itertools.product(*axes)) if axes else [()]
    ws, wr = _width(len(settings)), _width(spec.repetitions.count)
    out = Path(os.path.abspath(output_dir))
    members = []
    for si, combo in enumerate(settings):
        base = []
        values = {}
        for p, vi in zip(spec.parameters, combo):
            for k, vals in zip(p.keys, p.values):
                base.append((k, vals[vi]))
            values[p.name] = p.values[0][vi]
        for ri, seed in enumerate(spec.repetitions.seeds):
            sets = base + [(spec.repetitions.key, seed)]
            scene = copy.deepcopy(spec.scene_data)
            for k, v in sets:
                scene_keys.assign(scene, k, v)  # checked when the file was read
            has_dem = isinstance(scene.get("dem"), dict)
            threads = scene_keys.get(scene, "dem.threads", 0) if has_dem else 0
            if not isinstance(threads, int) or isinstance(threads, bool) or threads < 0:
                raise SweepError(f"{spec.scene}: dem.threads of member s{si}_r{ri} is "
                                 f"{threads!r}, not an integer >= 0")
            if threads == 0:
                # 0 would give every member all the cores: members get execution.threads.
                threads = spec.execution.threads
                if has_dem:
                    sets.append(("dem.threads", threads))
            gpu = has_dem and scene_keys.get(scene, "dem.backend", "cpu") == "cuda"
            checkpoints = ""
            if isinstance(scene.get("checkpoint"), dict):
                checkpoints = scene_keys.get(scene, "checkpoint.directory", "checkpoints")
                if not isinstance(checkpoints, str) or Path(checkpoints).is_absolute():
                    raise SweepError(
                        f"{spec.scene}: key 'checkpoint.directory' is {checkpoints!r}: a sweep "
                        "needs a path relative to the output folder, so that every member "
                        "has its own checkpoints")
            mid = f"s{si:0{ws}d}_r{ri:0{wr}d}"
            members.append(Member(
                index=len(members), id=mid, setting=si, repetition=ri, seed=seed,
                values=values, overrides=[f"{k}={scene_keys.toml_value(v)}" for k, v in sets],
                threads=threads, gpu=gpu, checkpoints=checkpoints,
                folder=str(out / "members" / mid)))
    return Plan(
        name=spec.name, sweep_file=str(Path(os.path.abspath(spec.file))), scene=str(spec.scene),
        scene_sha256=hashlib.sha256(scene_bytes).hexdigest(), output_dir=str(out),
        demfem_run=str(demfem_run), max_retries=spec.execution.max_retries,
        timeout=spec.execution.timeout, args=list(spec.execution.args),
        parameters=[{"name": p.name, "unit": p.unit, "keys": p.keys, "values": p.values}
                    for p in spec.parameters],
        members=members)


def identity(plan, member):
    """What makes a member's results: the scene's content and the overrides."""
    return {"sweep": plan.name, "scene": plan.scene, "scene_sha256": plan.scene_sha256,
            "overrides": member.overrides}


def check_identity(plan, member):
    """Refuses a member folder that was run with another scene or other overrides (the sweep
    file or the scene changed since): its results would be mixed with the new ones."""
    rec = read_json(Path(member.folder) / IDENTITY_FILE)
    if rec is None:
        return
    want = identity(plan, member)
    if rec.get("scene_sha256") != want["scene_sha256"]:
        why = (f"another version of the scene {rec.get('scene')} (its content changed since; "
               f"sha256 {rec.get('scene_sha256')} then, {want['scene_sha256']} now)")
    elif rec.get("overrides") != want["overrides"]:
        why = (f"other settings ({' '.join(rec.get('overrides') or [])}) than the sweep file "
               f"now gives it ({' '.join(want['overrides'])}): the parameters or seeds changed")
    else:
        return
    raise SweepError(f"{member.folder}: this member was run with {why}. Results of two sweeps "
                     "would be mixed: use another output folder (sweep.output_dir or "
                     "--output-dir), or remove this one")


def write_identity(plan, member):
    Path(member.folder).mkdir(parents=True, exist_ok=True)
    path = Path(member.folder) / IDENTITY_FILE
    if not path.exists():
        write_json_atomic(path, identity(plan, member), durable=False)


def save_plan(plan, path):
    write_json_atomic(path, plan.to_json())


def load_plan(path):
    d = read_json(path)
    if d is None:
        raise SweepError(f"{path}: not a sweep plan (missing or not JSON)")
    return Plan.from_json(d)
