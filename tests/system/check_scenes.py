#!/usr/bin/python3
"""ctest (issue 34, item 12): every TOML file under cases/ and examples/, found at test time
(a new scene is covered without a list to keep), is recognised by what it is:

  * a scene (it has the [run] table that every scene needs, docs/scenes.md): checked by
    `demfem_run SCENE --check` (the scene readers, meshes, STL, prepare scenes; nothing is
    started, nothing written), which must exit 0 and leave the folder it ran in empty;
  * a sweep file (it has the [sweep] table, docs/sweeps.md): read and planned by the sweep
    package (tools/sweep), which checks every key against its base scene;
  * anything else is an error: a file that is neither would be covered by nothing.

A scene with fem.backend = "external" whose program is a build product of its own example
(a relative path that the example's CMakeLists.txt builds with add_executable) is checked with
that program replaced by /bin/true when it is not built here: everything else of the scene is
checked; the example's own test builds the program and runs the scene.

  check_scenes.py SOURCE_DIR BUILD/bin/demfem_run
"""

import re
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

# demfem_run --check of a large scene (the sheet's 10^5 particles) takes 0.3 s; this only
# bounds a hang, it is not a speed requirement.
HANG_GUARD_S = 300


def kind(data):
    if "sweep" in data:
        return "sweep"
    if "run" in data:
        return "scene"
    return None


def built_by_example(scene, program):
    """Whether the relative `program` of `scene` is an executable that a CMakeLists.txt in the
    scene's folder (or one above it, up to examples/) builds."""
    if Path(program).is_absolute() or "/" not in program:
        return False
    name = Path(program).name
    for folder in [scene.parent, *scene.parent.parents]:
        cml = folder / "CMakeLists.txt"
        if cml.exists() and re.search(rf"add_executable\(\s*{re.escape(name)}\b",
                                      cml.read_text()):
            return True
        if folder.name == "examples":
            break
    return False


def check_scene(path, data, exe):
    args = []
    fem = data.get("fem", {})
    command = fem.get("command") if isinstance(fem, dict) else None
    note = ""
    if (isinstance(fem, dict) and fem.get("backend") == "external" and
            isinstance(command, list) and command and isinstance(command[0], str) and
            not (path.parent / command[0]).exists() and built_by_example(path, command[0])):
        stand_in = ["/bin/true"] + command[1:]
        args = ["--set", "fem.command=[" + ", ".join(f'"{a}"' for a in stand_in) + "]"]
        note = f" (its program {command[0]}, built by its example, replaced by /bin/true)"
    with tempfile.TemporaryDirectory(prefix="demfem-scene-check-") as tmp:
        try:
            r = subprocess.run([exe, str(path), "--check", *args], cwd=tmp, capture_output=True,
                               text=True, timeout=HANG_GUARD_S, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            return f"demfem_run --check did not end within {HANG_GUARD_S} s"
        left = sorted(str(p.relative_to(tmp)) for p in Path(tmp).rglob("*"))
    if r.returncode != 0:
        return f"demfem_run --check exited {r.returncode}:\n    " + \
            (r.stderr.strip() or r.stdout.strip()).replace("\n", "\n    ")
    if left:
        return f"demfem_run --check wrote {left[:5]}"
    return "ok" + note


def check_sweep(path, source):
    sys.path.insert(0, str(source / "tools"))
    from sweep.plan import build_plan
    from sweep.sweep_file import SweepError, read_sweep_file
    try:
        spec = read_sweep_file(path)
        plan = build_plan(spec, Path(tempfile.gettempdir()) / "unused", "/bin/true")
    except SweepError as e:
        return f"the sweep file is refused: {e}"
    return f"ok (sweep file: {len(plan.members)} members of {spec.scene.name})"


def main(argv):
    source, exe = Path(argv[1]).resolve(), str(Path(argv[2]).resolve())
    files = sorted(p for top in ("cases", "examples") for p in (source / top).rglob("*.toml"))
    failed, counts = 0, {"scene": 0, "sweep": 0}
    for path in files:
        rel = path.relative_to(source)
        try:
            data = tomllib.loads(path.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            result = f"not valid TOML: {e}"
        else:
            k = kind(data)
            if k is None:
                result = ("neither a scene (no [run] table) nor a sweep file (no [sweep] "
                          "table): nothing would check it")
            else:
                counts[k] += 1
                result = check_scene(path, data, exe) if k == "scene" else \
                    check_sweep(path, source)
        ok = result.startswith("ok")
        failed += not ok
        print(f"{rel}: {result}" if ok else f"FAILED {rel}: {result}")
    print(f"{counts['scene']} scene(s), {counts['sweep']} sweep file(s), {failed} failed")
    if counts["scene"] == 0:
        print("FAILED: no scenes found: the check would be empty")
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
