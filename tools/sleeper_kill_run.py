"""A long run that survives crashes, checked bit for bit (issue 15, "Long and fault-isolated").

Runs one coupled scene twice from the same prepared bed with the same binaries, at the same
time (each member single-threaded as the scene says, under `nice`):

  uninterrupted/  demfem_run SCENE, left alone;
  killed/         demfem_run SCENE, whose dem_server and fem_server this tool kills from outside
                  with SIGKILL (`--kill dem@T --kill fem@T2`: when the member's coupling.csv has
                  passed simulated time T, the solver process of that role, a child of the
                  member's demfem_run, gets SIGKILL, in the middle of whatever coupling step it
                  is computing). The run's own crash recovery does the rest: the coupler sees the
                  dead pid, starts the solver again (fem_server with --resume) and rolls every
                  process back to the last committed checkpoint (docs/reliability.md). The
                  scene needs a [checkpoint] section; its interval decides what a kill costs.

Then it compares the two output folders (the `compare` step, also on its own):

  * every CSV series (sensor_*.csv, fem_monitor.csv, fem_series.csv, coupling.csv without its
    wall-time columns wall_*) cell for cell, as text: the numbers are written with 17
    significant digits, so equal text is equal bits;
  * every HDF5 file of the output folder (particles_*, walls_*, fem_*, fem_mesh, coupling.h5)
    and the final checkpoint's dem.h5, fem.h5 and coupler.h5 (the run's end state), every
    dataset and attribute byte for byte (bin/demfem_h5_compare). Left out: coupler.h5's
    wall-time sums, last diagnostics row and output folder (measurements and names), and
    dem.h5's neighbour-list build positions (a cache that a restore rebuilds; see
    DEM_H5_SKIPPED). HDF5 files are not compared as files: HDF5 stores modification times;
  * the XDMF indexes, the [[post]] tools' reports and plots, byte for byte (a run's own
    folder name, which a report names, replaced by one word);
  * the same set of files on both sides (run.json, timing.csv, logs and locks excepted).

It prints every difference, a verdict, the members' wall and CPU times, what was killed when
(the coupler's own recovery messages), and exits 0 when everything is equal, 1 on any
difference, 2 on bad input, 3 when the members ended differently, or both failed alike
(then what they wrote is compared and the verdict printed all the same).

Run it in the folder whose out/ holds the prepared bed (the scene's [dem.load] finds it
there as `demfem run` does; a missing or stale bed is prepared first by each member, which
defeats the purpose: prepare it once with `demfem run` of the preparation scene):

    /usr/bin/python3 tools/sleeper_kill_run.py cases/sleeper_ci_100.toml \
        --workdir out/kill_run --kill dem@0.475 --kill fem@0.905 [--set KEY=VALUE]... \
        [--bin-dir build/bin] [--nice 10]
    /usr/bin/python3 tools/sleeper_kill_run.py compare out/kill_run/uninterrupted \
        out/kill_run/killed [--bin-dir build/bin]

The measured run of the CI bed (cases/sleeper_ci_100.toml set to 400 cycles, 47 minutes per
member, both solvers killed) is in docs/cases.md ("Long and fault-isolated");
tests/system/test_sleeper.cpp runs this comparison on a short version (the mini bed, each
solver killed once with the coupler's --debug-kill).
"""

import argparse
import csv
import json
import os
import re
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_BIN = os.path.join(os.path.dirname(HERE), "build", "bin")

# Not results: the run's record, wall times, logs, locks, partial files.
SKIPPED = re.compile(r"^(run\.json|timing\.csv|\.demfem\.lock|.*\.log|.*\.part)$")
# coupler.h5 of a checkpoint: the wall-time sums of the run so far, the run's own folder, and
# the last diagnostics row (coupling.csv's last row, wall times included; compared there).
COUPLER_H5_SKIPPED = ["@wall_", "@output_dir", "/last_diagnostics"]
# dem.h5 of a checkpoint: the neighbour list's build positions (particle centres bx, by, bz and
# polyhedron vertices vbuild at the last list build). A cache, not state: a restore rebuilds
# the list at once (DemSystem::restore sets need_rebuild), so after a recovery the builds fall
# on other steps than in the uninterrupted run. The list itself (row, nbr) and everything the
# particles carry are compared; the series show that the build steps change no result.
DEM_H5_SKIPPED = ["/dem/bx", "/dem/by", "/dem/bz", "/dem/vbuild"]


class BadInput(Exception):
    pass


# ---------------------------------------------------------------------------- the runs


def children(pid):
    """(pid, comm) of the processes whose parent is `pid`."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        # pid (comm) state ppid ...: comm may hold spaces, so split after the last ')'
        comm = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[1]) == pid:
            out.append((int(entry), comm))
    return out


def last_time(csv_path):
    """The simulated time of the last complete row of a coupling.csv (None before the first)."""
    try:
        with open(csv_path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 4096))
            tail = f.read().decode(errors="replace")
    except OSError:
        return None
    lines = tail.split("\n")
    complete = [l for l in lines[:-1] if l and not l.startswith("step")]
    if not complete:
        return None
    try:
        return float(complete[-1].split(",")[1])
    except (IndexError, ValueError):
        return None


def run_members(args):
    kills = []
    for k in args.kill:
        m = re.fullmatch(r"(dem|fem)@([0-9.eE+-]+)", k)
        if not m:
            raise BadInput(f"--kill {k!r}: expected dem@TIME or fem@TIME (TIME in s, > 0)")
        kills.append((m.group(1), float(m.group(2))))
    kills.sort(key=lambda k: k[1])
    if not os.path.isfile(args.scene):
        raise BadInput(f"{args.scene}: no such scene file")
    exe = os.path.join(args.bin_dir, "demfem_run")
    if not os.access(exe, os.X_OK):
        raise BadInput(f"{exe}: not an executable (--bin-dir)")
    os.makedirs(args.workdir, exist_ok=True)
    members = {}
    for name in ("uninterrupted", "killed"):
        out = os.path.abspath(os.path.join(args.workdir, name))
        cmd = ["nice", "-n", str(args.nice), exe, "--bin-dir", args.bin_dir, args.scene,
               "--quiet", "--output-dir", out]
        for s in args.set:
            cmd += ["--set", s]
        log = open(os.path.join(args.workdir, name + ".log"), "w")
        log.write("# " + " ".join(cmd) + "\n")
        log.flush()
        t0 = time.time()
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        members[name] = {"proc": p, "out": out, "start": t0, "log": log, "cmd": cmd}
        print(f"started {name}: pid {p.pid}: {' '.join(cmd)}", flush=True)

    killed = members["killed"]
    pending = list(kills)
    done_kills = []
    def running(m):
        # wait4: the member's CPU time (its solvers', restarted ones included, and its own)
        if "status" not in m:
            pid, status, usage = os.wait4(m["proc"].pid, os.WNOHANG)
            if pid == 0:
                return True
            m["status"] = os.waitstatus_to_exitcode(status)
            m["cpu_s"] = usage.ru_utime + usage.ru_stime
            m["end"] = time.time()
        return False

    try:
        while any([running(m) for m in members.values()]):
            if pending and running(killed):
                role, at = pending[0]
                t = last_time(os.path.join(killed["out"], "coupling.csv"))
                if t is not None and t >= at:
                    target = [c for c in children(killed["proc"].pid) if c[1] == role + "_server"]
                    if target:
                        pid = target[0][0]
                        os.kill(pid, signal.SIGKILL)
                        wall = time.time() - killed["start"]
                        done_kills.append({"role": role, "pid": pid, "asked_time": at,
                                           "csv_time_at_kill": t, "wall_s": wall})
                        print(f"SIGKILL {role}_server (pid {pid}) at wall {wall:.1f} s, "
                              f"coupling.csv at t = {t} s", flush=True)
                        pending.pop(0)
            time.sleep(0.25)
    except KeyboardInterrupt:
        for m in members.values():
            if "status" not in m:
                os.killpg(m["proc"].pid, signal.SIGTERM)
        raise
    summary = {"scene": args.scene, "overrides": args.set, "kills": done_kills,
               "kills_not_done": [{"role": r, "time": t} for r, t in pending], "members": {}}
    for name, m in members.items():
        m["log"].close()
        summary["members"][name] = {"status": m["status"],
                                    "wall_s": round(m["end"] - m["start"], 1),
                                    "cpu_s": round(m["cpu_s"], 1), "command": m["cmd"]}
    summary["load_average_at_end"] = os.getloadavg()
    # What the coupler said about the deaths and recoveries
    with open(os.path.join(args.workdir, "killed.log")) as f:
        summary["recovery_messages"] = [l.rstrip() for l in f
                                        if re.search(r"failed|recovered|restarting|started ", l)]
    with open(os.path.join(args.workdir, "kill_run.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(json.dumps(summary, indent=1), flush=True)
    return summary


# ---------------------------------------------------------------------------- the comparison


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def compare_csv(a, b, name):
    ra, rb = read_rows(a), read_rows(b)
    if not ra or not rb:
        return [] if ra == rb else [f"{name}: one side is empty"]
    if ra[0] != rb[0]:
        return [f"{name}: headers differ"]
    keep = [i for i, h in enumerate(ra[0]) if not (name == "coupling.csv" and h.startswith("wall"))]
    diffs = []
    if len(ra) != len(rb):
        diffs.append(f"{name}: {len(ra) - 1} rows against {len(rb) - 1}")
    for n, (x, y) in enumerate(zip(ra[1:], rb[1:]), start=2):
        for i in keep:
            xv = x[i] if i < len(x) else None
            yv = y[i] if i < len(y) else None
            if xv != yv:
                diffs.append(f"{name}:{n}: column {ra[0][i]}: {xv} against {yv}")
                break
        if len(diffs) > 5:
            diffs.append(f"{name}: ... (more)")
            break
    return diffs


def compare_h5(a, b, name, bin_dir, skip=()):
    exe = os.path.join(bin_dir, "demfem_h5_compare")
    cmd = [exe, a, b]
    for s in skip:
        cmd += ["--skip", s]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode == 0:
        return []
    text = (r.stdout + r.stderr).strip().splitlines()
    return [f"{name}: {line}" for line in text[:8]]


def compare_bytes(a, b, name, folders):
    """Byte for byte, after each run's own folder name is replaced by one word (a report
    names the folder it read)."""
    with open(a, "rb") as fa, open(b, "rb") as fb:
        xa, xb = fa.read(), fb.read()
    def anonymous(data, folder):
        # as given, absolute, relative to here: longest first
        forms = {folder, os.path.normpath(folder), os.path.abspath(folder), os.path.relpath(folder)}
        for f in sorted(forms, key=len, reverse=True):
            data = data.replace(f.encode(), b"<output>")
        return data

    xa, xb = anonymous(xa, folders[0]), anonymous(xb, folders[1])
    return [] if xa == xb else [f"{name}: bytes differ"]


def last_checkpoint(out):
    d = os.path.join(out, "checkpoints")
    if not os.path.isdir(d):
        return None
    steps = sorted(s for s in os.listdir(d) if re.fullmatch(r"step-\d+", s)
                   and os.path.isfile(os.path.join(d, s, "manifest.json")))
    return os.path.join(d, steps[-1]) if steps else None


def compare(a, b, bin_dir):
    """Differences between output folders a and b, and how many items were compared."""
    for d in (a, b):
        if not os.path.isdir(d):
            raise BadInput(f"{d}: no such output folder")
    if not os.access(os.path.join(bin_dir, "demfem_h5_compare"), os.X_OK):
        raise BadInput(f"{bin_dir}/demfem_h5_compare: not built (--bin-dir)")
    fa = {f for f in os.listdir(a) if os.path.isfile(os.path.join(a, f)) and not SKIPPED.match(f)}
    fb = {f for f in os.listdir(b) if os.path.isfile(os.path.join(b, f)) and not SKIPPED.match(f)}
    diffs = [f"{f}: only in {a}" for f in sorted(fa - fb)]
    diffs += [f"{f}: only in {b}" for f in sorted(fb - fa)]
    counts = {"csv": 0, "h5": 0, "bytes": 0}
    for f in sorted(fa & fb):
        pa, pb = os.path.join(a, f), os.path.join(b, f)
        if f.endswith(".csv"):
            diffs += compare_csv(pa, pb, f)
            counts["csv"] += 1
        elif f.endswith(".h5"):
            diffs += compare_h5(pa, pb, f, bin_dir)
            counts["h5"] += 1
        else:
            diffs += compare_bytes(pa, pb, f, (a, b))
            counts["bytes"] += 1
    # The end state: the last checkpoint of each run (the end of the run writes one)
    ca, cb = last_checkpoint(a), last_checkpoint(b)
    if ca is None or cb is None:
        diffs.append(f"final checkpoint missing: {ca} / {cb}")
    elif os.path.basename(ca) != os.path.basename(cb):
        diffs.append(f"last checkpoints differ: {ca} against {cb}")
    else:
        for part in ("dem.h5", "fem.h5", "coupler.h5"):
            pa, pb = os.path.join(ca, part), os.path.join(cb, part)
            if os.path.exists(pa) or os.path.exists(pb):
                skip = {"coupler.h5": COUPLER_H5_SKIPPED, "dem.h5": DEM_H5_SKIPPED}.get(part, [])
                diffs += compare_h5(pa, pb, "checkpoint " + os.path.basename(ca) + "/" + part,
                                    bin_dir, skip)
                counts["h5"] += 1
    return diffs, counts, ca


def settlement_at_end(out):
    """Mean uz of the fem_monitor probes b*_uz at the last row (the report's settlement)."""
    rows = read_rows(os.path.join(out, "fem_monitor.csv"))
    cols = [i for i, h in enumerate(rows[0]) if re.fullmatch(r"b\d+_uz", h)]
    if not cols:
        return None
    last = rows[-1]
    return float(last[0]), sum(float(last[i]) for i in cols) / len(cols)


def report(a, b, bin_dir):
    diffs, counts, cp = compare(a, b, bin_dir)
    for d in diffs:
        print("DIFFERENT: " + d)
    print(f"compared {counts['csv']} CSV series, {counts['h5']} HDF5 files (every dataset and "
          f"attribute), {counts['bytes']} other files byte for byte; end state "
          f"{os.path.basename(cp) if cp else None}")
    try:
        t, s = settlement_at_end(b)
        print(f"settlement at t = {t} s: {s * 1e3:.3f} mm (mean uz of the bottom-face probes)")
    except (OSError, TypeError, IndexError, ValueError):
        pass
    print("VERDICT: " + ("bitwise equal" if not diffs else f"{len(diffs)} difference(s)"))
    return 0 if not diffs else 1


def main(argv):
    if argv and argv[0] == "compare":
        p = argparse.ArgumentParser(prog="sleeper_kill_run.py compare")
        p.add_argument("a")
        p.add_argument("b")
        p.add_argument("--bin-dir", default=DEFAULT_BIN)
        args = p.parse_args(argv[1:])
        try:
            return report(args.a, args.b, os.path.abspath(args.bin_dir))
        except BadInput as e:
            print(f"sleeper_kill_run.py: {e}", file=sys.stderr)
            return 2
    p = argparse.ArgumentParser(prog="sleeper_kill_run.py", description=__doc__.split("\n")[0])
    p.add_argument("scene")
    p.add_argument("--workdir", required=True)
    p.add_argument("--kill", action="append", default=[], help="dem@TIME or fem@TIME (s)")
    p.add_argument("--set", action="append", default=[], help="KEY=VALUE, to both members")
    p.add_argument("--bin-dir", default=DEFAULT_BIN)
    p.add_argument("--nice", type=int, default=10)
    args = p.parse_args(argv)
    args.bin_dir = os.path.abspath(args.bin_dir)
    try:
        summary = run_members(args)
    except BadInput as e:
        print(f"sleeper_kill_run.py: {e}", file=sys.stderr)
        return 2
    status = {n: m["status"] for n, m in summary["members"].items()}
    if status["uninterrupted"] != status["killed"]:
        print(f"VERDICT: the members ended differently: {status} (see {args.workdir}/*.log)")
        return 3
    if status["killed"] != 0:
        # Both failed alike (e.g. the same blow-up): what they wrote up to it is still compared;
        # a run that failed is not a long run that survived, so the exit status stays 3.
        print(f"note: both members ended with status {status['killed']} (see {args.workdir}/*.log); "
              "comparing what they wrote")
    if summary["kills_not_done"]:
        print("note: kills not done (the run ended first): " + str(summary["kills_not_done"]))
    try:
        code = report(os.path.join(args.workdir, "uninterrupted"),
                      os.path.join(args.workdir, "killed"), args.bin_dir)
        return code if status["killed"] == 0 or code != 0 else 3
    except BadInput as e:
        print(f"sleeper_kill_run.py: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
