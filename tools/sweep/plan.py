"""The members of a sweep: every setting (the Cartesian product of the parameters, each
parameter's keys zipped) times every repetition, with the overrides that make each one, its
thread count and whether it needs a GPU."""

import copy
import hashlib
import itertools
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from sweep import scene_keys
from sweep.records import IDENTITY_FILE, read_json, write_json_atomic
from sweep.stages import stage_overrides
from sweep.sweep_file import MAX_MEMBERS_LIMIT, SweepError, read_text


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
    # With [[stage]]: per stage in order {"name", "overrides", "checkpoints" (relative to the
    # stage's folder), "folder" (<folder>/<name>)}; empty: the member is one run.
    stages: list = field(default_factory=list)


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
    stages: list = field(default_factory=list)  # [{"name", "scene", "scene_sha256"}]
    # The folder members run in ("" = each its own): with [execution] beds = "shared",
    # <output_dir>/beds, where the beds that [dem.load] scene prepares are made once per
    # variant and shared by every member that asks for it.
    run_dir: str = ""

    def to_json(self):
        d = asdict(self)
        return d

    @staticmethod
    def from_json(d):
        d = dict(d)
        d["members"] = [Member(**m) for m in d["members"]]
        return Plan(**d)


def member_count(spec):
    n = spec.repetitions.count
    for p in spec.parameters:
        n *= p.count
    return n


def too_many_members(spec, total):
    axes = " x ".join(f"{p.count} ({p.name})" for p in spec.parameters) or "1 setting"
    return (f"{spec.file}: the sweep has {total} members ({axes} x {spec.repetitions.count} "
            f"repetition(s)), more than execution.max_members = {spec.execution.max_members}. "
            "Every member is a folder with its own run, logs and records, and the plan lists "
            "them all (docs/sweeps.md, \"How many members\"): split the study into several "
            "sweeps, or raise [execution] max_members (at most "
            f"{MAX_MEMBERS_LIMIT}) if this is meant")


def _escapes(path_text):
    """Whether a folder, relative to the member's folder, lies outside it."""
    norm = os.path.normpath(path_text)
    return os.path.isabs(path_text) or norm == ".." or norm.startswith("../")


def _set_value(sets, key):
    """The value that a [dem.load] set entry "KEY=VALUE" gives `key`, or None."""
    for entry in sets if isinstance(sets, list) else []:
        if isinstance(entry, str) and "=" in entry and entry.split("=", 1)[0].strip() == key:
            try:
                return tomllib.loads("v = " + entry.split("=", 1)[1])["v"]
            except tomllib.TOMLDecodeError:
                return None  # demfem_run --check names it
    return None


def _prepare_problem(path, sets, depth=0):
    """Where the prepare scene at `path` (a [dem.load] scene, with its `set` overrides), or one
    it prepares in turn, writes its state outside the folder the run starts in: None when
    nowhere. An unreadable scene is left to demfem_run --check, which names it."""
    try:
        data = tomllib.loads(read_text(path, "a scene file (TOML)"))
    except (SweepError, tomllib.TOMLDecodeError):
        return None
    run = data.get("run") if isinstance(data.get("run"), dict) else {}
    out = _set_value(sets, "run.output_dir")
    where = f"its [dem.load] set \"run.output_dir=...\" of {path}"
    if out is None:
        out = run.get("output_dir", "out")
        where = f"{path}: key 'run.output_dir'"
    if isinstance(out, str) and _escapes(out):
        return (f"{where} is {out!r}, outside the member's folder (a prepare scene's "
                "run.output_dir is relative to the folder the run starts in, the member's): "
                "members would write the same bed folder. Give it a relative folder without "
                "'..' (the default is out/<run.name>)")
    load = data.get("dem", {}).get("load") if isinstance(data.get("dem"), dict) else None
    if isinstance(load, dict) and isinstance(load.get("scene"), str) and depth < 16:
        return _prepare_problem(Path(path).parent / load["scene"], load.get("set", []),
                                depth + 1)
    return None


def member_paths(scene_path, scene, mid, overrides, cache):
    """Checks that every folder the member writes lies inside its own folder (its scene with
    its overrides: checkpoint.directory, the output folders of the beds that [dem.load]
    prepares); returns the checkpoint folder relative to the member folder ("" = none)."""
    checkpoints = ""
    if isinstance(scene.get("checkpoint"), dict):
        checkpoints = scene_keys.get(scene, "checkpoint.directory", "checkpoints")
        if not isinstance(checkpoints, str) or _escapes(checkpoints):
            set_by = [o for o in overrides if o.startswith("checkpoint")]
            raise SweepError(
                f"{scene_path}: key 'checkpoint.directory' of member {mid} is {checkpoints!r}"
                + (f" (from the sweep's --set {' '.join(set_by)})" if set_by else "") +
                ": a sweep needs a relative path inside the member's folder (no '..' out of "
                "it), so that every member has its own checkpoints")
    dem = scene.get("dem")
    load = dem.get("load") if isinstance(dem, dict) else None
    if isinstance(load, dict) and isinstance(load.get("scene"), str):
        sets = load.get("set", [])
        key = (load["scene"], repr(sets))
        if key not in cache:
            cache[key] = _prepare_problem(Path(scene_path).parent / load["scene"], sets)
        if cache[key]:
            raise SweepError(f"member {mid} prepares its bed with {load['scene']}: {cache[key]}")
    return checkpoints


def _width(n):
    return max(2, len(str(max(n - 1, 0))))


def build_plan(spec, output_dir, demfem_run, progress=None):
    """The members in order. `progress(done, total)`, when given, is called every 10^4
    members (a large plan takes seconds)."""
    total = member_count(spec)
    if total > spec.execution.max_members:
        raise SweepError(too_many_members(spec, total))
    scene_bytes = spec.scene.read_bytes()
    axes = [range(p.count) for p in spec.parameters]
    settings = itertools.product(*axes) if axes else [()]
    ws, wr = _width(total // spec.repetitions.count), _width(spec.repetitions.count)
    out = Path(os.path.abspath(output_dir))
    members = []
    checked_paths = {}
    for si, combo in enumerate(settings):
        base = []
        values = {}
        for p, vi in zip(spec.parameters, combo):
            for k, vals in zip(p.keys, p.values):
                base.append((k, vals[vi]))
            values[p.name] = p.values[0][vi]
        # One copy per setting: a repetition sets the same key each time (its seed), so the
        # copy is reused and only that key is written again. (With stages, each stage's
        # scene gets only the keys it takes: _member_stages.)
        scene = None if spec.stages else copy.deepcopy(spec.scene_data)
        for k, v in base:
            if scene is not None:
                scene_keys.assign(scene, k, v)  # checked when the file was read
        base_text = [f"{k}={scene_keys.toml_value(v)}" for k, v in base]
        # Without [repetitions] a parameter may set the seed key itself (a study whose seeds
        # are an axis zipped with other keys): its value is the member's seed, not the
        # scene's, which would otherwise be written after it and win.
        own_seed = dict(base).get(spec.repetitions.key)
        for ri, seed in enumerate(spec.repetitions.seeds):
            if own_seed is not None:
                seed = own_seed
            overrides = base_text + [f"{spec.repetitions.key}={scene_keys.toml_value(seed)}"]
            mid = f"s{si:0{ws}d}_r{ri:0{wr}d}"
            folder = out / "members" / mid
            if spec.stages:
                stages, threads, gpu = _member_stages(spec, mid, overrides, folder,
                                                      checked_paths)
                checkpoints = ""
            else:
                scene_keys.assign(scene, spec.repetitions.key, seed)
                stages = []
                threads, gpu, checkpoints = _single_run(spec, scene, mid, overrides,
                                                        checked_paths)
            members.append(Member(
                index=len(members), id=mid, setting=si, repetition=ri, seed=seed,
                values=values, overrides=overrides, threads=threads, gpu=gpu,
                checkpoints=checkpoints, folder=str(folder), stages=stages))
            if progress and len(members) % 10000 == 0:
                progress(len(members), total)
    return Plan(
        name=spec.name, sweep_file=str(Path(os.path.abspath(spec.file))), scene=str(spec.scene),
        scene_sha256=hashlib.sha256(scene_bytes).hexdigest(), output_dir=str(out),
        demfem_run=str(demfem_run), max_retries=spec.execution.max_retries,
        timeout=spec.execution.timeout, args=list(spec.execution.args),
        parameters=[{"name": p.name, "unit": p.unit, "keys": p.keys, "values": p.values}
                    for p in spec.parameters],
        members=members,
        run_dir=str(out / "beds") if spec.execution.beds == "shared" else "",
        stages=[{"name": st.name, "scene": str(st.scene),
                 "scene_sha256": hashlib.sha256(st.scene.read_bytes()).hexdigest()}
                for st in spec.stages])


def _threads_of(scene_path, scene, what):
    """The scene's dem.threads (0 without [dem]), checked."""
    has_dem = isinstance(scene.get("dem"), dict)
    threads = scene_keys.get(scene, "dem.threads", 0) if has_dem else 0
    if not isinstance(threads, int) or isinstance(threads, bool) or threads < 0:
        raise SweepError(f"{scene_path}: dem.threads of {what} is {threads!r}, not an "
                         "integer >= 0")
    return threads, has_dem


def _single_run(spec, scene, mid, overrides, checked_paths):
    """A member that is one run of the scene (with its overrides applied to `scene`): its
    threads (dem.threads appended to `overrides` where the scene leaves it 0), whether it
    needs a GPU, its checkpoint folder."""
    threads, has_dem = _threads_of(spec.scene, scene, f"member {mid}")
    if threads == 0:
        # 0 would give every member all the cores: members get execution.threads.
        threads = spec.execution.threads
        if has_dem:
            overrides.append(f"dem.threads={threads}")
    gpu = has_dem and scene_keys.get(scene, "dem.backend", "cpu") == "cuda"
    return threads, gpu, member_paths(spec.scene, scene, mid, overrides, checked_paths)


def _member_stages(spec, mid, overrides, folder, checked_paths):
    """The stages of member `mid`: each one's overrides (the member's that it gets, its
    `set` with the folders of the earlier stages, dem.threads where its scene leaves it 0),
    checkpoint folder; and the member's threads (the most of any stage: they run one after
    the other) and whether a stage needs a GPU."""
    stages, folders, threads, gpu = [], {}, 1, False
    for st in spec.stages:
        own = stage_overrides(st, overrides, folders)
        scene = copy.deepcopy(st.scene_data)
        for o in own:
            key, value = o.split("=", 1)
            scene_keys.assign(scene, key, tomllib.loads("v = " + value)["v"])
        n, has_dem = _threads_of(st.scene, scene, f"member {mid}, stage {st.name},")
        if n == 0:
            n = spec.execution.threads
            if has_dem:
                own.append(f"dem.threads={n}")
        threads = max(threads, n)
        gpu = gpu or (has_dem and scene_keys.get(scene, "dem.backend", "cpu") == "cuda")
        checkpoints = member_paths(st.scene, scene, f"{mid} (stage {st.name})", own,
                                   checked_paths)
        folders[st.name] = str(folder / st.name)
        stages.append({"name": st.name, "overrides": own, "checkpoints": checkpoints,
                       "folder": folders[st.name]})
    return stages, threads, gpu


def identity(plan, member):
    """What makes a member's results: the scene's content and the overrides (with stages:
    each stage's scene content and overrides too)."""
    out = {"sweep": plan.name, "scene": plan.scene, "scene_sha256": plan.scene_sha256,
           "overrides": member.overrides}
    if member.stages:
        out["stages"] = [{"name": ps["name"], "scene_sha256": ps["scene_sha256"],
                          "overrides": ms["overrides"]}
                         for ps, ms in zip(plan.stages, member.stages)]
    return out


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
    elif rec.get("stages") != want.get("stages"):
        why = ("other stages (their scenes' content or their overrides changed since: "
               f"{rec.get('stages')} then, {want.get('stages')} now)")
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
