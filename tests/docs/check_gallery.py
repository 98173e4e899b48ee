#!/usr/bin/python3
"""ctest: the case gallery (docs/gallery.md) covers every scene. Every scene file of cases/,
examples/*/ and docs/tutorials/ is named in it and in the picture script's list
(tools/gallery_pictures.py, SCENES), every scene row of its tables ends with a picture, and
every picture it shows is in docs/.

  check_gallery.py SOURCE_DIR
"""
import glob
import importlib.util
import os
import re
import sys


def main(source):
    failures = []
    scenes = sorted(os.path.relpath(p, source) for pattern in
                    ("cases/*.toml", "examples/*/*.toml", "docs/tutorials/*.toml")
                    for p in glob.glob(os.path.join(source, pattern)))
    with open(os.path.join(source, "docs", "gallery.md"), encoding="utf-8") as f:
        gallery = f.read()
    spec = importlib.util.spec_from_file_location(
        "gallery_pictures", os.path.join(source, "tools", "gallery_pictures.py"))
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    for scene in scenes:
        name = os.path.basename(scene)
        if f"`{scene}`" not in gallery and f"`{name}`" not in gallery:
            failures.append(f"docs/gallery.md does not name {scene}")
        if scene not in script.SCENES:
            failures.append(f"tools/gallery_pictures.py (SCENES) has no entry for {scene}")
    for scene in script.SCENES:
        if scene not in scenes:
            failures.append(f"tools/gallery_pictures.py names {scene}, which is not a scene")
    rows = [line for line in gallery.split("\n")  # scene rows (sweep files are no scenes)
            if line.startswith("| `") and ".toml`" in line.split(" | ")[0]
            and not line.startswith("| `cases/sweeps/")]
    for row in rows:
        last = row.rstrip(" |").rsplit(" | ", 1)[-1]
        if "![" not in last:
            failures.append(f"a gallery row without a picture: {row[:80]}")
    for png in re.findall(r"\]\((figures/[^)]+\.png)\)", gallery):
        if not os.path.isfile(os.path.join(source, "docs", png)):
            failures.append(f"docs/gallery.md shows {png}, which is not in docs/")
    for f in failures:
        print("FAILED:", f)
    print(f"{len(scenes)} scenes, {len(rows)} gallery rows:", "FAILED" if failures else "passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
