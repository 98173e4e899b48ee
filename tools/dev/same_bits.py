#!/usr/bin/python3
"""Same bits: do two builds of demfem compute the same numbers?

  tools/dev/same_bits.py --build BUILD_DIR [--cases beam,sheet,sleeper,sweep,dem]
                         [--json FILE] [--keep DIR]

Runs the reference cases with BUILD_DIR's programs (the scenes of the source tree that
BUILD_DIR was configured from) in fresh folders and prints one hash per case over its
numbers: every dataset of every HDF5 output file (read through h5dump as little-endian
binary, so that HDF5's object time stamps do not count), every CSV cell except the wall-time
columns (wall_*) and timing.csv, and the XDMF indexes. Checkpoints, logs, plots, run.json and
reports (which hold wall times and dates) are left out. The DEM case is the state hash of
bench/poly_throughput (spheres and 10/30/40-triangle rocks, 1 and 2 threads).

Run it on the build before a refactoring and on the build after: the tables must be equal
(issue 35). --json writes each file's hash, to find the file that differs.

  beam     cases/beam_checkpoint_ci.toml (the coupled beam under spheres, 50 coupling steps)
  sheet    cases/sheet_ci.toml (prepares its fill first; about a minute)
  sleeper  cases/sleeper_ci.toml (prepares its two beds first; about a minute)
  sweep    cases/sweeps/beam_load_ci.toml: summary.csv and series_deflection.csv
  dem      bench/poly_throughput --counts 300 --state-hash, --threads 1 and 2
"""

import argparse
import csv
import hashlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SKIP_DIRS = {"checkpoints", "plots", "members", "slurm"}
SKIP_FILES = {"timing.csv", "run.json", "members.csv"}


def source_of(build):
    cache = (build / "CMakeCache.txt").read_text()
    m = re.search(r"^CMAKE_HOME_DIRECTORY:INTERNAL=(.*)$", cache, re.M)
    if not m:
        sys.exit(f"same_bits: {build}/CMakeCache.txt names no source folder")
    return Path(m.group(1))


def csv_hash(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return hashlib.sha256(b"").hexdigest()
    keep = [k for k, name in enumerate(rows[0]) if not name.startswith("wall_")]
    text = "\n".join(",".join(r[k] for k in keep if k < len(r)) for r in rows)
    return hashlib.sha256(text.encode()).hexdigest()


def h5_hash(path):
    listing = subprocess.run(["h5ls", "-r", str(path)], capture_output=True, text=True,
                             check=True).stdout
    h = hashlib.sha256()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "d.bin"
        for line in sorted(listing.splitlines()):
            name, _, kind = line.partition(" ")
            if not kind.strip().startswith("Dataset"):
                continue
            subprocess.run(["h5dump", "-d", name, "-b", "LE", "-o", str(out), str(path)],
                           capture_output=True, check=True)
            h.update(name.encode() + b"\0" + out.read_bytes())
    return h.hexdigest()


def folder_hashes(root):
    hashes = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d not in SKIP_DIRS)
        for name in sorted(filenames):
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            if name in SKIP_FILES:
                continue
            if name.endswith(".h5"):
                hashes[rel] = h5_hash(p)
            elif name.endswith(".csv"):
                hashes[rel] = csv_hash(p)
            elif name.endswith(".xdmf"):
                hashes[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return hashes


def combined(hashes):
    h = hashlib.sha256()
    for rel in sorted(hashes):
        h.update(f"{rel}:{hashes[rel]}\n".encode())
    return h.hexdigest()[:16]


def run_case(build, source, scene, tmp):
    r = subprocess.run([str(build / "bin" / "demfem_run"), str(source / "cases" / scene),
                        "--quiet", "--no-post"], cwd=tmp, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"same_bits: {scene} exited {r.returncode}:\n{r.stderr[-2000:]}")
    return folder_hashes(Path(tmp) / "out")


def run_sweep(build, source, tmp):
    out = Path(tmp) / "sweep"
    env = dict(os.environ, PYTHONPATH=str(source / "tools"))
    r = subprocess.run([sys.executable, "-m", "sweep",
                        str(source / "cases" / "sweeps" / "beam_load_ci.toml"),
                        "--output-dir", str(out), "--demfem-run", str(build / "bin" / "demfem_run"),
                        "--no-plots", "--no-check", "--progress-interval", "0"],
                       capture_output=True, text=True, env=env)
    if r.returncode != 0:
        sys.exit(f"same_bits: the sweep exited {r.returncode}:\n{r.stderr[-2000:]}")
    return {n: csv_hash(out / n) for n in ("summary.csv", "series_deflection.csv")}


def run_dem(build):
    hashes = {}
    for threads in (1, 2):
        r = subprocess.run([str(build / "bench" / "poly_throughput"), "--counts", "300",
                            "--threads", str(threads), "--state-hash"],
                           capture_output=True, text=True, cwd=tempfile.gettempdir())
        if r.returncode != 0:
            sys.exit(f"same_bits: poly_throughput exited {r.returncode}:\n{r.stderr[-2000:]}")
        found = re.findall(r"\b[0-9a-f]{16}\b", r.stdout)
        if not found:
            sys.exit("same_bits: poly_throughput printed no state hash")
        hashes[f"threads={threads}"] = " ".join(found)
    return hashes


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", required=True, type=Path)
    ap.add_argument("--cases", default="dem,beam,sweep,sheet,sleeper")
    ap.add_argument("--json", type=Path, help="write every file's hash here")
    args = ap.parse_args()
    missing = [t for t in ("h5ls", "h5dump") if shutil.which(t) is None]
    if missing:  # the HDF5 outputs are read through them (Debian: hdf5-tools)
        sys.exit(f"same_bits.py: {' and '.join(missing)} not found: install hdf5-tools "
                 "(apt-get install hdf5-tools)")
    build = args.build.resolve()
    source = source_of(build)
    scenes = {"beam": "beam_checkpoint_ci.toml", "sheet": "sheet_ci.toml",
              "sleeper": "sleeper_ci.toml"}
    table, detail = [], {}
    for case in args.cases.split(","):
        with tempfile.TemporaryDirectory(prefix=f"same-bits-{case}-") as tmp:
            if case == "dem":
                hashes = run_dem(build)
            elif case == "sweep":
                hashes = run_sweep(build, source, tmp)
            elif case in scenes:
                hashes = run_case(build, source, scenes[case], tmp)
            else:
                sys.exit(f"same_bits: unknown case {case!r} (beam, sheet, sleeper, sweep, dem)")
        detail[case] = hashes
        table.append((case, len(hashes), combined(hashes)))
        if case == "dem":
            for k, v in hashes.items():
                print(f"  dem {k}: {v}", flush=True)
        print(f"{case:8s} {len(hashes):4d} files  {table[-1][2]}", flush=True)
    if args.json:
        args.json.write_text(json.dumps({"source": str(source), "cases": detail}, indent=1))


if __name__ == "__main__":
    main()
