#!/usr/bin/python3
"""ctest: the full-scale tiled sleeper chains (cases/sleeper_tiled.toml and
sleeper_tiled_cells026.toml, eight prepare scenes each) take a seed: `--set run.seed=S` on the
load case reaches every scene of the chain (each [dem.load] passes run.seed on), the second
layer's pour with S and the first layer's block with S - 1 (sleeper_pour2_tiled*.toml,
seed_offset = -1; docs/cases.md, "Full scale: the commands").

`demfem_run --check` walks the chain and packs each scene's rocks without running anything, so
a seed whose block does not fit its column would be refused here, naming the block's
dem.pack[0].count (seeds 1-40 need 3.62-4.41 m of the 4.49 m column). Checked: seeds 2 and 3
(the tallest columns among 1-40 after the shift: blocks 1 and 2, 4.24 and 4.41 m), 13 and 41
pass, each scene of the chain named valid; seed 0 would give the block -1 and is refused by
the second layer's seed_offset, naming the least seed (1) - which shows the shift acts along
the chain. Nothing is written.

  check_tiled_seeds.py SOURCE_DIR BUILD/bin/demfem_run
"""

import subprocess
import sys
import tempfile
from pathlib import Path

CHAINS = {
    "sleeper_tiled.toml": ["sleeper_block1", "sleeper_block1_compact", "sleeper_pour1_tiled",
                           "sleeper_bed1_tiled", "sleeper_pour2_tiled", "sleeper_compact2_tiled",
                           "sleeper_bed2_tiled", "sleeper_land_tiled", "sleeper_tiled"],
    "sleeper_tiled_cells026.toml": ["sleeper_block1", "sleeper_block1_compact",
                                    "sleeper_pour1_tiled", "sleeper_bed1_tiled_cells026",
                                    "sleeper_pour2_tiled_cells026",
                                    "sleeper_compact2_tiled_cells026",
                                    "sleeper_bed2_tiled_cells026",
                                    "sleeper_land_tiled_cells026", "sleeper_tiled_cells026"],
}
failures = 0


def check(ok, what, detail=""):
    global failures
    print(("ok      " if ok else "FAILED  ") + what + ("" if ok else "\n    " + detail))
    failures += 0 if ok else 1


def main(argv):
    cases, exe = Path(argv[1]).resolve() / "cases", str(Path(argv[2]).resolve())
    for scene, chain in CHAINS.items():
        for seed in (2, 3, 13, 41):
            with tempfile.TemporaryDirectory(prefix="demfem-tiled-seed-") as tmp:
                r = subprocess.run([exe, str(cases / scene), "--check", "--set",
                                    f"run.seed={seed}"], cwd=tmp, capture_output=True,
                                   text=True, timeout=300, stdin=subprocess.DEVNULL)
                left = list(Path(tmp).iterdir())
            text = r.stdout + r.stderr
            named = [s for s in chain if f"{s}.toml: the scene is valid" not in text]
            check(r.returncode == 0 and not named and not left,
                  f"{scene} --set run.seed={seed}: every scene of its chain valid, nothing written",
                  f"exit {r.returncode}; not named valid: {named}; written: {left}\n    " +
                  text.strip().replace("\n", "\n    "))
        with tempfile.TemporaryDirectory(prefix="demfem-tiled-seed-") as tmp:
            r = subprocess.run([exe, str(cases / scene), "--check", "--set", "run.seed=0"],
                               cwd=tmp, capture_output=True, text=True, timeout=300,
                               stdin=subprocess.DEVNULL)
        check(r.returncode == 2 and "'dem.load.seed_offset'" in r.stderr and
              "run.seed=0" in r.stderr and "at least 1" in r.stderr,
              f"{scene} --set run.seed=0: refused (exit 2), the block's seed would be -1",
              f"exit {r.returncode}:\n    " + r.stderr.strip().replace("\n", "\n    "))
    print(f"{failures} failed" if failures else "all passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
