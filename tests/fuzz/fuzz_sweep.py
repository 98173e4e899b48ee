#!/usr/bin/python3
"""A mutation fuzzer, in pure Python, of the sweep file's reader and planner (tools/sweep:
read_sweep_file, build_plan, and the sbatch script of its [slurm] table).

    python3 tests/fuzz/fuzz_sweep.py SECONDS [--seed N] [--findings DIR]
    python3 tests/fuzz/fuzz_sweep.py --replay [FILE_OR_DIR ...]

The seeds are the sweep files of cases/sweeps/ and tests/fuzz/corpus/sweep/ (hand-written
seeds from the sweep tests, and findings once fixed). Each input is a mutation of a seed (bytes
flipped, inserted, deleted or repeated; lines deleted, repeated, swapped or spliced from
another seed; tokens of TOML and of the sweep schema inserted; numbers replaced by edge
values) and is written as `sweeps/fuzz.toml` into a scratch folder that holds copies of the
scenes of cases/ (the seeds' base scenes and the beds they prepare) and the unit tests' scene.
A finding is
  * any exception other than the package's own clear error, SweepError (exit status 2);
  * a hang: one input taking more than HANG_S seconds (SIGALRM), or memory past MEMORY_LIMIT;
  * a broken promise of the checks (docs/sweeps.md): an sbatch script line that is not one of
    the lines the script is made of (a value that smuggled a line in), a member override
    whose value does not read back as itself, a member folder or checkpoint folder outside
    the sweep's folder.
Findings are written to --findings (default fuzz-out/sweep/) as finding-<sha1>.toml with a
.txt beside it (the traceback); after the fix the input goes into corpus/sweep/, which ctest
replays (`--replay`, test "fuzz_replay: sweep"). Exit status: 0 no finding, 1 findings.
"""

import argparse
import hashlib
import os
import random
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import tomllib
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parents[1]
sys.path.insert(0, str(SOURCE / "tools"))

from sweep import scene_keys, slurm  # noqa: E402
from sweep.plan import build_plan  # noqa: E402
from sweep.sweep_file import SweepError, read_sweep_file  # noqa: E402

HANG_S = 20               # one input; a plan of 10^4 members takes 0.3 s
MEMORY_LIMIT = 4 << 30    # bytes of address space: a runaway read fails instead of swapping
CORPUS = HERE / "corpus" / "sweep"
UNIT_SCENE = """[run]
end_time = 0.01
[dem]
dt = 2e-6
[[dem.pairs]]
friction = 0.3
[[dem.insert]]
mass = 30.0
[checkpoint]
every_steps = 10
"""
NUMBERS = ["1e309", "-1", "0", "nan", "inf", "-inf", "true", "1979-05-27", "0.0", "1e-320",
           "9223372036854775808", "99999999999999999999", "1000000", "10001", "-0.0"]
TOKENS = NUMBERS + [
    "\n", "\r", "\t", "\x00", " ", "=", "[", "]", "[[", "]]", "{", "}", ",", "\"", "'", '"""',
    ".", "..", "../", "/", "#", "\\n", "\\u0000", "\\\\", "-", "+", "e", "[]", "{}",
    "[[parameter]]", "[parameter.keys]", "[sweep]", "[slurm]",
    "[execution]", "[repetitions]", "[[quantity]]", "scene", "name", "output_dir", "keys",
    "unit", "count", "seeds", "first_seed", "key", "threads", "max_retries", "timeout", "jobs",
    "args", "max_members", "partition", "time", "account", "qos", "mem", "max_concurrent",
    "options", "file", "column", "time_column", "at", "method", "reduce", "window", "last",
    "relative_to", '"run.seed"', '"run.output_dir"', '"checkpoint.directory"', '"dem.threads"',
    '"dem.backend"', '"dem.load.scene"', '"dem.pairs[0].friction"', '"dem.pairs[99].x"',
    '"cuda"', '"/dev/zero"', '"/dev/null"', '"/"', '"."', '"../../x"', '"--output=/x"',
    '"--wrap=id"', '"a\\nb"', "[1, 2, 3]", "[1000, 1000]", '["a", "b"]',
]


class Finding(Exception):
    pass


def setup(root):
    """The scratch folder: copies of the scenes of cases/ (the seeds' base scenes and the beds
    they prepare, by the same relative paths), and the unit tests' scene.toml."""
    (root / "sweeps").mkdir(parents=True)
    for p in (SOURCE / "cases").glob("*.toml"):
        shutil.copy(p, root / p.name)
    (root / "sweeps" / "scene.toml").write_text(UNIT_SCENE)


def seeds():
    files = sorted((SOURCE / "cases" / "sweeps").glob("*.toml")) + sorted(CORPUS.glob("*"))
    return [(p, p.read_bytes()) for p in files if p.is_file()]


def _alarm(sig, frame):
    raise Finding(f"hang: one input took more than {HANG_S} s")


SCRIPT_PREFIXES = ("#!/bin/bash", "# demfem sweep ", "export PYTHONPATH=", "exec ")


def target(data, root):
    """Reads and plans `data` as a sweep file; raises Finding for anything but a clean
    SweepError, returns a short description otherwise."""
    f = root / "sweeps" / "fuzz.toml"
    f.write_bytes(data)
    out = root / "out"
    signal.alarm(HANG_S)
    try:
        spec = read_sweep_file(f)
        plan = build_plan(spec, out, "/bin/true")
        check_plan(plan, out)
        text = slurm.script_text(plan, out / "slurm" / "plan.json", 1, False, spec.slurm)
        for line in text.split("\n"):
            # An #SBATCH line is one option, one word (sbatch splits it at blanks).
            sbatch = line.startswith("#SBATCH -") and len(line.split()) == 2
            if line and not sbatch and not line.startswith(SCRIPT_PREFIXES):
                raise Finding(f"the sbatch script has a line of its own: {line!r}")
        return f"planned {len(plan.members)} member(s)"
    except SweepError as e:
        return "refused: " + str(e).splitlines()[0][:80]
    except Finding:
        raise
    except RecursionError:
        raise Finding("RecursionError:\n" + traceback.format_exc())
    except BaseException as e:  # noqa: B902 (MemoryError, KeyboardInterrupt from a child...)
        if isinstance(e, KeyboardInterrupt):
            raise
        raise Finding(f"{type(e).__name__}:\n" + traceback.format_exc())
    finally:
        signal.alarm(0)


def check_plan(plan, out):
    folder = Path(os.path.abspath(out))
    for m in plan.members[:200]:
        if Path(m.folder).parent != folder / "members":
            raise Finding(f"member folder {m.folder} outside {folder}/members")
        if m.checkpoints:
            ck = os.path.normpath(os.path.join(m.folder, m.checkpoints))
            if ck != m.folder and not ck.startswith(m.folder + os.sep):
                raise Finding(f"checkpoint folder {m.checkpoints!r} of {m.id} leaves its folder")
        for o in m.overrides:
            key, _, value = o.partition("=")
            try:
                tomllib.loads("v = " + value)
            except tomllib.TOMLDecodeError:
                raise Finding(f"override {o!r} of {m.id} is not TOML that reads back")


# What the structured mutations put into a sweep file's tables (besides the seeds' own keys).
SCHEMA = {
    "sweep": ["scene", "name", "output_dir"],
    "parameter": ["keys", "name", "unit"],
    "repetitions": ["count", "seeds", "first_seed", "key"],
    "execution": ["threads", "max_retries", "timeout", "jobs", "args", "max_members"],
    "slurm": ["partition", "time", "account", "qos", "mem", "max_concurrent", "options"],
    "quantity": ["name", "file", "column", "time_column", "unit", "at", "method", "reduce",
                 "window", "last", "relative_to"],
}
STRINGS = ["", "x", "run.seed", "dem.threads", "checkpoint.directory", "run.output_dir",
           "dem.load.scene", "dem.backend", "dem.pairs[0].friction", "dem.pairs[7].friction",
           "a\nb", "a\rb", "\x00", "../../x", "/abs/x", "..", ".", "/dev/zero", "/dev/null",
           "/", "a b", "--output=/x", "--wrap=id", "-o/x", "--exclusive", "8G", "1:00:00",
           "cuda", "cpu", "max", "series", "final", "mean", "at", "linear", "nearest",
           "coupling.csv", "x" * 300, "%A", "$(id)", "'", '"', "\\", "é", "\u2028"]


def random_value(rng, depth=0):
    k = rng.randrange(10)
    if k == 0:
        return rng.choice([0, 1, -1, 2, 7, 10000, 10001, 1000000, 2**63 - 1, -2**63, 2**31])
    if k == 1:
        return rng.choice([0.0, -0.0, 1e-320, 1e308, -1.5, 0.5, float("nan"), float("inf"),
                           float("-inf"), 1e-6, 0.01])
    if k == 2:
        return rng.choice([True, False])
    if k in (3, 4, 5):
        return rng.choice(STRINGS)
    if k == 6 and depth < 2:
        return [random_value(rng, depth + 1) for _ in range(rng.choice((0, 1, 2, 3, 50)))]
    if k == 7 and depth < 2:
        return {rng.choice(STRINGS + sum(SCHEMA.values(), [])): random_value(rng, depth + 1)
                for _ in range(rng.randint(0, 3))}
    if k == 8:
        return [rng.uniform(-1, 1) for _ in range(rng.choice((1, 2, 100, 1001)))]
    return [rng.randrange(100) for _ in range(rng.choice((1, 2, 3)))]


def _containers(node, path=()):
    """Every dict and list of the parsed file with its path."""
    yield path, node
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for k, v in items:
        if isinstance(v, (dict, list)):
            yield from _containers(v, path + (k,))


def mutate_structure(rng, data):
    """Parses the seed, changes a value, key or array of it and writes it back as TOML
    (inline tables): valid TOML that reaches the checks behind the syntax."""
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    for _ in range(rng.choice((1, 1, 2, 3))):
        path, node = rng.choice(list(_containers(doc)))
        op = rng.randrange(4)
        if isinstance(node, dict):
            table = next((t for t in reversed(path) if isinstance(t, str) and t in SCHEMA), None)
            if op == 0 and node:                       # delete a key
                del node[rng.choice(list(node))]
            elif op == 1 and table:                    # add or set a key of the schema
                node[rng.choice(SCHEMA[table])] = random_value(rng)
            elif op == 2 and not path:                 # a new table
                name = rng.choice(list(SCHEMA))
                node.setdefault(name, {} if name not in ("parameter", "quantity") else [{}])
            elif node:                                 # change a value
                node[rng.choice(list(node))] = random_value(rng)
        elif node:
            i = rng.randrange(len(node))
            if op == 0:
                del node[i]
            elif op == 1:
                node.insert(i, node[i])
            else:
                node[i] = random_value(rng) if not isinstance(node[i], dict) else node[i]
    try:
        return "\n".join(f"{scene_keys._toml_key(k)} = {scene_keys.toml_value(v)}"
                         for k, v in doc.items()).encode()
    except TypeError:
        return None


def mutate(rng, data, pool):
    if rng.random() < 0.5:
        out = mutate_structure(rng, data)
        if out is not None:
            return out
    data = bytearray(data)
    for _ in range(rng.choice((1, 1, 2, 3, 5))):
        op = rng.randrange(9)
        n = len(data)
        if op == 0 and n:       # change a byte (mostly to ASCII: most others are not UTF-8)
            data[rng.randrange(n)] = rng.randrange(256 if rng.random() < 0.1 else 128)
        elif op == 1:           # insert a token
            t = rng.choice(TOKENS).encode()
            i = rng.randint(0, n)
            data[i:i] = t
        elif op == 2 and n:     # delete a range
            i = rng.randrange(n)
            del data[i:i + rng.randint(1, 16)]
        elif op == 3 and n:     # repeat a range
            i = rng.randrange(n)
            j = min(n, i + rng.randint(1, 64))
            data[i:i] = data[i:j] * rng.randint(1, 4)
        else:                   # line operations
            lines = bytes(data).split(b"\n")
            k = rng.randrange(len(lines))
            if op == 4:
                del lines[k]
            elif op == 5:
                lines.insert(k, lines[rng.randrange(len(lines))])
            elif op == 6:
                j = rng.randrange(len(lines))
                lines[k], lines[j] = lines[j], lines[k]
            elif op == 7:       # splice a line of another seed
                other = rng.choice(pool).split(b"\n")
                lines.insert(k, rng.choice(other))
            else:               # replace a number by an edge value
                words = lines[k].split(b" ")
                for w, word in enumerate(words):
                    if word[:1].isdigit() or word[:1] == b"-":
                        words[w] = rng.choice(NUMBERS).encode()
                        break
                lines[k] = b" ".join(words)
            data = bytearray(b"\n".join(lines))
    return bytes(data[:1 << 16])


def signature(why):
    """One finding per kind: the exception's type and the line that raised it (a traceback),
    or the broken promise's first words."""
    if "Traceback" not in why:
        return why.split(":")[0][:80]
    frames = re.findall(r'File "([^"]+)", line (\d+)', why)
    where = f"{Path(frames[-1][0]).name}:{frames[-1][1]}" if frames else "?"
    return f"{why.splitlines()[0]} at {where}"


def save(findings, data, why):
    findings.mkdir(parents=True, exist_ok=True)
    h = hashlib.sha1(data).hexdigest()[:16]
    (findings / f"finding-{h}.toml").write_bytes(data)
    (findings / f"finding-{h}.txt").write_text(why + "\n")
    return findings / f"finding-{h}.toml"


def fuzz(seconds, seed, findings):
    rng = random.Random(seed)
    pool = [d for _, d in seeds()]
    found = {}
    runs = 0
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="demfem-fuzz-sweep-") as tmp:
        root = Path(tmp)
        setup(root)
        while time.monotonic() - t0 < seconds:
            data = mutate(rng, rng.choice(pool), pool)
            runs += 1
            try:
                target(data, root)
            except Finding as e:
                why = str(e)
                kind = signature(why)
                if kind not in found:
                    found[kind] = save(findings, data, why)
                    print(f"finding {len(found)} after {runs} runs: {kind} -> {found[kind]}",
                          flush=True)
            shutil.rmtree(root / "out", ignore_errors=True)
    print(f"fuzz_sweep: {runs} runs in {time.monotonic() - t0:.0f} s (seed {seed}), "
          f"{len(found)} distinct finding(s)")
    return 1 if found else 0


def replay(paths):
    files = []
    for p in [Path(x) for x in paths] or [CORPUS, SOURCE / "cases" / "sweeps"]:
        files += sorted(q for q in p.iterdir() if q.is_file()) if p.is_dir() else [p]
    failed = 0
    with tempfile.TemporaryDirectory(prefix="demfem-fuzz-sweep-") as tmp:
        root = Path(tmp)
        setup(root)
        for p in files:
            try:
                result = target(p.read_bytes(), root)
                print(f"{p.name}: {result}")
            except Finding as e:
                failed += 1
                print(f"FAILED {p}: {e}")
            shutil.rmtree(root / "out", ignore_errors=True)
    print(f"{len(files)} input(s) replayed, {failed} failed")
    return 1 if failed or not files else 0


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("seconds", nargs="?", type=float, help="how long to fuzz")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the time)")
    p.add_argument("--findings", default=str(SOURCE / "fuzz-out" / "sweep"),
                   help="folder for findings (default fuzz-out/sweep/)")
    p.add_argument("--replay", nargs="*", metavar="FILE_OR_DIR",
                   help="run these inputs once (default: corpus/sweep/ and cases/sweeps/)")
    a = p.parse_args(argv)
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    signal.signal(signal.SIGALRM, _alarm)
    if a.replay is not None:
        return replay(a.replay)
    if a.seconds is None or a.seconds <= 0:
        p.error("give SECONDS > 0, or --replay")
    seed = a.seed if a.seed is not None else int(time.time())
    return fuzz(a.seconds, seed, Path(a.findings))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
