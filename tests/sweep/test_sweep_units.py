#!/usr/bin/python3
"""ctest: the pieces of tools/sweep without running members: the Student-t quantile against
closed forms and published table values, scene keys and their TOML text, the strict sweep
file reader (messages with file, line, key), the plan, the extraction of quantities against
hand-computed values, the retry classification and the sbatch script."""

import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
import unittest
from pathlib import Path

from sweep_testing import sweep_file_case, write  # first: it puts tools/ on sys.path

from sweep import exit_status, scene_keys, slurm, stats
from sweep.collect import extract, interpolate
from sweep.member import Handle, classify, describe_exit
from sweep.plan import build_plan
from sweep.sweep_file import Quantity, SlurmOptions, SweepError, read_sweep_file

SCENE = """
[run]
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


class StudentT(unittest.TestCase):
    def test_closed_forms(self):
        # df = 1 is Cauchy: t_p = tan(pi (p - 1/2)); df = 2: t_p = (2p - 1) / sqrt(2 p (1 - p)).
        for p in (0.9, 0.95, 0.975, 0.995):
            self.assertAlmostEqual(stats.student_t_quantile(p, 1), math.tan(math.pi * (p - 0.5)),
                                   delta=1e-12 * math.tan(math.pi * (p - 0.5)))
            t2 = (2 * p - 1) / math.sqrt(2 * p * (1 - p))
            self.assertAlmostEqual(stats.student_t_quantile(p, 2), t2, delta=1e-12 * t2)

    def test_table(self):
        # Published two-sided 95 % values (e.g. NIST/SEMATECH e-Handbook, table 1.3.6.7.2),
        # given to 3 decimals.
        for df, t in ((3, 3.182), (4, 2.776), (5, 2.571), (9, 2.262), (10, 2.228), (20, 2.086),
                      (30, 2.042), (100, 1.984)):
            self.assertAlmostEqual(stats.student_t_quantile(0.975, df), t, delta=5e-4)

    def test_summarise(self):
        n, mean, sd, lo, hi = stats.summarise([1.0, 2.0, 3.0, 4.0])
        self.assertEqual((n, mean), (4, 2.5))
        self.assertAlmostEqual(sd, math.sqrt(5.0 / 3.0), delta=1e-15)
        self.assertAlmostEqual(hi - mean, 3.182446305284263 * sd / 2.0, delta=1e-5)
        self.assertTrue(math.isnan(stats.summarise([1.0])[2]))
        self.assertEqual(stats.summarise([])[0], 0)


class SceneKeys(unittest.TestCase):
    def test_parse_and_assign(self):
        scene = tomllib.loads(SCENE)
        scene_keys.assign(scene, "dem.pairs[0].friction", 0.5)
        scene_keys.assign(scene, "dem.threads", 2)  # added to an existing table
        self.assertEqual(scene["dem"]["pairs"][0]["friction"], 0.5)
        self.assertEqual(scene_keys.get(scene, "dem.threads"), 2)
        self.assertIsNone(scene_keys.get(scene, "dem.walls[0].stl"))
        for key, why in (("dem.walls[0].stl", "no array 'dem.walls'"),
                         ("dem.pairs[1].friction", "'dem.pairs' has 1 entries"),
                         ("fem.dt", "no table 'fem'"), ("dem.dt.x", "'dem.dt' is not a table"),
                         ("dem..dt", "not a dotted scene key"), ("dem.pairs[x]", "not a dotted")):
            with self.assertRaisesRegex(scene_keys.KeyError_, why.replace("[", r"\[")):
                scene_keys.assign(tomllib.loads(SCENE), key, 1)

    def test_pass_only_keys(self):
        # a key under [dem.load] pass that this scene has no place for goes to the bed only
        scene = tomllib.loads(SCENE + '[dem.load]\nscene = "bed.toml"\npass = ["dem.shapes", "run.seed"]\n')
        self.assertFalse(scene_keys.assign(scene, "dem.shapes[0].triangles", 30))
        self.assertNotIn("shapes", scene["dem"])
        self.assertTrue(scene_keys.assign(scene, "run.seed", 4))  # [run] exists: applied here
        self.assertEqual(scene["run"]["seed"], 4)
        with self.assertRaisesRegex(scene_keys.KeyError_, "no array 'dem.walls'"):
            scene_keys.assign(scene, "dem.walls[0].stl", 1)  # not under pass: refused
        self.assertTrue(scene_keys.under("dem.pairs[0].friction", "dem.pairs"))
        self.assertFalse(scene_keys.under("dem.pairsx", "dem.pairs"))

    def test_toml_text_reads_back(self):
        for v in (0.1, 1e-5, 2.0, 210e9, -3, True, "cuda", 'a "q" \\ é', [1, 2.5, "x"],
                  {"kind": "constant", "diameter": 0.024}, [[0.0, 1.0], [2.0, 3.0]]):
            text = scene_keys.toml_value(v)
            self.assertEqual(tomllib.loads(f"v = {text}")["v"], v, text)


def wait_file(path, guard=60.0):
    deadline = time.monotonic() + guard
    while not Path(path).exists() and time.monotonic() < deadline:
        time.sleep(0.01)


SWEEP = """\
[sweep]
scene = "scene.toml"
name = "t"

[[parameter]]
name = "mass"
unit = "kg"
[parameter.keys]
"dem.insert[0].mass" = [10.0, 20.0]

[[parameter]]
[parameter.keys]
"dem.pairs[0].friction" = [0.1, 0.2, 0.3]

[repetitions]
count = 2
first_seed = 5

[[quantity]]
name = "q"
file = "coupling.csv"
column = "x"
reduce = "max"
"""


# A folder with the scene; reads sweep files written there (no tests of its own).
SweepFileCase = sweep_file_case({"scene.toml": SCENE})


class SweepFile(SweepFileCase):
    def test_plan(self):
        spec = self.read(SWEEP)
        plan = build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        self.assertEqual(len(plan.members), 2 * 3 * 2)
        m = plan.members[7]  # setting 3 = (mass index 1, friction index 0), repetition 1
        self.assertEqual((m.id, m.setting, m.repetition, m.seed), ("s03_r01", 3, 1, 6))
        self.assertEqual(m.values, {"mass": 20.0, "dem.pairs[0].friction": 0.1})
        # dem.threads is 0 in the scene: members get execution.threads (1), said by --set.
        self.assertEqual(m.overrides, ["dem.insert[0].mass=20.0", "dem.pairs[0].friction=0.1",
                                       "run.seed=6", "dem.threads=1"])
        self.assertEqual((m.threads, m.gpu, m.checkpoints), (1, False, "checkpoints"))

    def test_stop_after_the_run_finished_counts_as_done(self):
        # A stop that reaches demfem_run after it wrote run.json "completed" (the signal then
        # ends the process on its way out, exit 130): the run is whole, the member is done,
        # not "interrupted" (CI saw the record and the next sweep's count disagree).
        from sweep import member as member_mod
        stand_in = write(self.tmp.name, "demfem_run",
                         "#!/bin/sh\nprintf '{\"status\": \"completed\", \"exit_code\": 0}' "
                         "> run.json\nexec sleep 60\n")
        os.chmod(stand_in, 0o755)
        plan = build_plan(self.read(SWEEP), Path(self.tmp.name) / "out", str(stand_in))
        m = plan.members[0]
        h = Handle()
        threading.Thread(target=lambda: (wait_file(Path(m.folder) / "run.json"),
                                         h.interrupt()), daemon=True).start()
        rec = member_mod.run_member(plan, m, handle=h, log=lambda *a: None)
        self.assertEqual((rec["state"], rec["attempts"][-1]["exit"]), ("done", 130))
        self.assertEqual(len(rec["attempts"]), 1)
        # Without the finished run record the same stop leaves it interrupted.
        m = plan.members[1]
        write(self.tmp.name, "demfem_run", "#!/bin/sh\nexec sleep 60\n")
        h = Handle()
        threading.Thread(target=lambda: (wait_file(Path(m.folder) / "attempt-1.log"),
                                         time.sleep(0.2), h.interrupt()), daemon=True).start()
        rec = member_mod.run_member(plan, m, handle=h, log=lambda *a: None)
        self.assertEqual(rec["state"], "interrupted")

    def test_zipped_keys(self):
        spec = self.read(SWEEP.replace('"dem.insert[0].mass" = [10.0, 20.0]',
                                       '"dem.insert[0].mass" = [10.0, 20.0]\n'
                                       '"dem.dt" = [1e-6, 2e-6]'))
        plan = build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        self.assertEqual(plan.members[-1].overrides[:2],
                         ["dem.insert[0].mass=20.0", "dem.dt=2e-06"])

    def test_seed_as_a_parameter(self):
        # Without [repetitions] a parameter may set run.seed (seeds zipped with other keys):
        # its value is the member's seed; the scene's own seed is not written after it.
        text = SWEEP[:SWEEP.index("[repetitions]")] + SWEEP[SWEEP.index("[[quantity]]"):]
        spec = self.read(text.replace('"dem.insert[0].mass" = [10.0, 20.0]',
                                      '"dem.insert[0].mass" = [10.0, 20.0]\n'
                                      '"run.seed" = [8, 9]'))
        plan = build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        for m in plan.members:
            seed = [8, 9][m.setting // 3]
            seeds = [o for o in m.overrides if o.startswith("run.seed=")]
            self.assertEqual((m.seed, set(seeds)), (seed, {f"run.seed={seed}"}))

    def test_errors_name_file_line_key(self):
        f = str(Path(self.tmp.name) / "s.toml")
        self.refused(SWEEP + "typo = 1\n", f"{f}:24: key 'quantity[0].typo'", "not a known key")
        self.refused("typo = 1\n" + SWEEP, f"{f}:1: key 'typo'", "not a known key")
        self.refused(SWEEP.replace("count = 2", "count = 0"), f"{f}:16: key 'repetitions.count'",
                     "[1, 100000]")
        self.refused(SWEEP.replace("[0.1, 0.2, 0.3]", "[0.1, 0.2]").replace(
            '"dem.insert[0].mass" = [10.0, 20.0]',
            '"dem.insert[0].mass" = [10.0, 20.0]\n"dem.dt" = [1e-6]'),
            "key 'parameter[0].keys.\"dem.dt\"'", "zipped")
        self.refused(SWEEP.replace('"dem.pairs[0].friction"', '"dem.pairs[4].friction"'),
                     f"{f}:13:", "'dem.pairs' has 1 entries")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "median"'),
                     "quantity[0].reduce", '"final", "max", "min", "mean", "series"')
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "max"\nat = 0.1'), "exactly one")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "mean"\nwindow = [2, 1]'),
                     "t0 < t1")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "mean"\nlast = 0'),
                     "quantity[0].last", "range > 0")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "mean"\nlast = 1\nwindow = [0, 1]'),
                     "exactly one of 'window'")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "final"\nlast = 1'),
                     "does not apply to 'final'")
        self.refused(SWEEP.replace('reduce = "max"', 'reduce = "max"\nrelative_to = "seated"'),
                     "quantity[0].relative_to", "must be a number")
        self.refused(SWEEP.replace("first_seed = 5", "seeds = [1, 1]"), "a seed twice")
        self.refused(SWEEP.replace('scene = "scene.toml"', 'scene = "nope.toml"'),
                     "key 'sweep.scene'", "cannot read")
        self.refused(SWEEP.replace('name = "q"', 'name = "mass"'), "already a column")
        self.refused(SWEEP + "[execution]\nargs = [\"--resume\"]\n", "set by the sweep itself")
        self.refused(SWEEP + "[slurm]\ntime = \"ten minutes\"\n", "a Slurm time")
        self.refused(SWEEP.replace("first_seed = 5", 'key = "dem.pairs[0].friction"'),
                     "is also a parameter")

    def test_files_that_are_not_text(self):
        # Found by tests/fuzz/fuzz_sweep.py: a device as the scene was read without end, a
        # sweep file that is not UTF-8 raised UnicodeDecodeError; a FIFO would block.
        import os
        fifo = Path(self.tmp.name) / "fifo.toml"
        os.mkfifo(fifo)
        for scene, why in (("/dev/zero", "is not a regular file"), (str(fifo), "not a regular"),
                           (".", "is a directory")):
            self.refused(SWEEP.replace('scene = "scene.toml"', f'scene = "{scene}"'),
                         "key 'sweep.scene'", why, "expected a scene file (TOML)")
        p = Path(self.tmp.name) / "bad.toml"
        p.write_bytes(SWEEP.encode().replace(b'name = "t"', b'name = "t\x9b"'))
        with self.assertRaisesRegex(SweepError, "is not UTF-8 text .byte 38.; expected a sweep "
                                    "file"):
            read_sweep_file(p)

    def test_inline_tables_have_lines(self):
        # (fuzz_sweep.py's structured inputs are inline tables: their messages had no line)
        f = str(Path(self.tmp.name) / "s.toml")
        self.refused('quantity = [{ name = "a", file = "c.csv", column = "x", reduce = "max" },'
                     '\n  { name = "b", typo = 1 }]\n[sweep]\nscene = "scene.toml"\n',
                     f"{f}:1: key 'quantity[1]")

    def test_absolute_checkpoint_folder_is_refused(self):
        write(self.tmp.name, "scene.toml", SCENE + 'directory = "/tmp/ck"\n')
        spec = self.read(SWEEP)
        with self.assertRaisesRegex(SweepError, "checkpoint.directory"):
            build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")


class Injection(SweepFileCase):
    """Issue 34, item 2: every value that reaches the sbatch script (or a folder name) is
    checked; a newline would be a shell command of the script."""

    def test_sweep_file_values_with_control_characters(self):
        cmd = "\\ntouch /tmp/demfem-injected"   # TOML escape: a newline in the value
        for table, key, value, part in (
                ("slurm", "partition", f'"debug{cmd}"', "key 'slurm.partition'"),
                ("slurm", "account", f'"proj{cmd}"', "key 'slurm.account'"),
                ("slurm", "qos", f'"normal{cmd}"', "key 'slurm.qos'"),
                ("slurm", "mem", f'"8G{cmd}"', "key 'slurm.mem'"),
                ("slurm", "time", f'"10{cmd}"', "key 'slurm.time'"),
                ("slurm", "options", f'["--exclusive", "--constraint=a100{cmd}"]',
                 "key 'slurm.options'"),
                ("execution", "args", f'["--quiet{cmd}"]', "key 'execution.args'")):
            text = SWEEP + f"[{table}]\n{key} = {value}\n"
            msg = self.refused(text, part, "U+000A")
            self.assertIn(":25:", msg)  # the key's line
        self.refused(SWEEP.replace('name = "t"', 'name = "t"\noutput_dir = "out/a\\nb"'),
                     "key 'sweep.output_dir'", "U+000A")
        self.refused(SWEEP.replace('unit = "kg"', 'unit = "kg\\rx"'), "parameter[0].unit",
                     "U+000D")

    def test_slurm_values_that_are_not_one_word(self):
        for key, value, part in (
                ("partition", '"debug --wrap=x"', "a partition name"),
                ("account", '"a;b"', "an account name"),
                ("qos", '"$(id)"', "a QOS name"),
                ("mem", '"8 G"', "a Slurm size"),
                ("options", '["--exclusive --wrap=x"]', "one sbatch option as one word"),
                ("options", '["--comment=\\"x y\\""]', "one sbatch option as one word"),
                ("options", '["exclusive"]', "one sbatch option as one word"),
                ("options", '["--output=/tmp/x"]', "sets --output"),
                ("options", '["--chd=/tmp"]', "sets --chdir"),
                ("options", '["-o/tmp/x"]', "sets --output"),
                ("options", '["--array=0-9"]', "sets --array")):
            self.refused(SWEEP + f"[slurm]\n{key} = {value}\n", f"key 'slurm.{key}'", part)
        spec = self.read(SWEEP + '[slurm]\npartition = "gpu,debug"\naccount = "proj-1"\n'
                         'qos = "high"\nmem = "8G"\noptions = ["--constraint=a100&nvlink", '
                         '"-Cv100", "--exclusive", "--mail-type=END"]\n')
        self.assertEqual(spec.slurm.partition, "gpu,debug")

    def test_script_text_refuses_what_it_cannot_carry(self):
        class P:
            name, output_dir = "beam", "/scratch/beam"
        for opt in (SlurmOptions(partition="a\ntouch /tmp/x"),
                    SlurmOptions(options=["--exclusive\ntouch /tmp/x"])):
            with self.assertRaisesRegex(SweepError, "U\\+000A"):
                slurm.script_text(P, Path("/p.json"), 1, False, opt)
        for folder, why in (("/scratch/my beam", "' '"), ("/scratch/a\nb", "U\\+000A"),
                            ("/scratch/100%", "'%'"), ('/scratch/"x"', "'\"'")):
            P.output_dir = folder
            with self.assertRaisesRegex(SweepError, "the sweep folder .*" + why):
                slurm.script_text(P, Path("/p.json"), 1, False, SlurmOptions())
        # The shell lines quote their words: a checkout path with a blank stays one word.
        P.output_dir = "/scratch/beam"
        text = slurm.script_text(P, Path("/scratch/beam/slurm/plan 1.json"), 1, False,
                                 SlurmOptions())
        self.assertIn("--member-task '/scratch/beam/slurm/plan 1.json'", text)

    def test_command_line_values(self):
        from sweep import cli
        sweep_file = write(self.tmp.name, "s.toml", SWEEP)
        out = Path(self.tmp.name) / "out"
        for extra, part in ((["--partition", "debug\ntouch /tmp/x"], "--partition: is"),
                            (["--mem", "8G;id"], "--mem: is"),
                            (["--sbatch-option=--exclusive\nid"],
                             "[slurm] options or --sbatch-option"),
                            (["--output-dir", str(out) + "\nid"], "--output-dir")):
            args = [str(sweep_file), "--slurm", "--no-check", "--demfem-run", "/bin/true",
                    "--output-dir", str(out)] + extra
            err = _stderr_of(cli.main, args)
            self.assertEqual(err[0], 2, err[1])
            self.assertIn(part, err[1])
            self.assertFalse(out.exists(), "something was written before the refusal")


def _stderr_of(fn, *args):
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stderr(buf), contextlib.redirect_stdout(io.StringIO()):
        code = fn(*args)
    return code, buf.getvalue()


class MemberFolders(SweepFileCase):
    """Issue 34, item 8: every folder a member writes stays inside its own folder."""

    def plan(self, text=SWEEP):
        return build_plan(self.read(text), Path(self.tmp.name) / "out", "/bin/true")

    def test_checkpoint_directory(self):
        for d in ("../../../x", "a/../../x", ".."):
            write(self.tmp.name, "scene.toml", SCENE + f'directory = "{d}"\n')
            with self.assertRaisesRegex(SweepError, "checkpoint.directory' of member s00_r00 is "
                                        f"'{re.escape(d)}'.*inside the member's folder"):
                self.plan()
        write(self.tmp.name, "scene.toml", SCENE + 'directory = "a/../ck"\n')
        self.assertEqual(self.plan().members[0].checkpoints, "a/../ck")  # stays inside
        write(self.tmp.name, "scene.toml", SCENE)
        text = SWEEP.replace('"dem.insert[0].mass" = [10.0, 20.0]',
                             '"dem.insert[0].mass" = [10.0, 20.0]\n'
                             '"checkpoint.directory" = ["ck", "../ck"]')
        with self.assertRaisesRegex(SweepError, r"member s03_r00 is '../ck' \(from the sweep's "
                                    r"--set checkpoint.directory=\"../ck\"\)"):
            self.plan(text)

    def test_output_dir_is_the_sweeps(self):
        self.refused(SWEEP.replace('"dem.pairs[0].friction" = [0.1, 0.2, 0.3]',
                                   '"run.output_dir" = ["a", "b"]'),
                     "key 'parameter[1].keys.\"run.output_dir\"'", "set by the sweep itself")
        self.refused(SWEEP.replace("first_seed = 5", 'key = "run.output_dir"'),
                     "key 'repetitions.key'", "set by the sweep itself")

    def test_prepared_beds(self):
        write(self.tmp.name, "bed1.toml", '[run]\nend_time = 1.0\noutput_dir = "/tmp/beds"\n')
        write(self.tmp.name, "bed2.toml", '[run]\nend_time = 1.0\n[dem.load]\nscene = '
              '"bed1.toml"\n')
        load = '[dem.load]\nscene = "bed2.toml"\npass = ["run.seed"]\n'
        write(self.tmp.name, "scene.toml", SCENE.replace("[[dem.pairs]]", load + "[[dem.pairs]]"))
        with self.assertRaisesRegex(SweepError, "member s00_r00 prepares its bed with bed2.toml"
                                    ".*bed1.toml: key 'run.output_dir' is '/tmp/beds', outside"):
            self.plan()
        write(self.tmp.name, "bed1.toml", '[run]\nend_time = 1.0\n')
        self.assertEqual(len(self.plan().members), 12)
        write(self.tmp.name, "scene.toml", SCENE.replace(
            "[[dem.pairs]]", load + "set = ['run.output_dir=\"../../beds\"']\n[[dem.pairs]]"))
        with self.assertRaisesRegex(SweepError, "set \"run.output_dir=...\" of .*bed2.toml is "
                                    "'../../beds', outside"):
            self.plan()


class MemberCount(SweepFileCase):
    """Issue 34, item 9: a cap on the members, and progress while planning a large sweep."""

    def big(self, n_a, n_b, extra=""):
        return (SWEEP.replace("[10.0, 20.0]", repr([10.0 + i for i in range(n_a)]))
                .replace("[0.1, 0.2, 0.3]", repr([0.1 + i * 1e-3 for i in range(n_b)])) + extra)

    def test_cap(self):
        spec = self.read(self.big(1000, 1000))   # 10^6 settings x 2 repetitions
        with self.assertRaisesRegex(SweepError, r"2000000 members \(1000 \(mass\) x 1000 "
                                    r"\(dem.pairs\[0\].friction\) x 2 repetition\(s\)\), more "
                                    r"than execution.max_members = 10000"):
            build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        self.refused(SWEEP + "[execution]\nmax_members = 1000001\n",
                     "key 'execution.max_members'", "[1, 1000000]")
        spec = self.read(SWEEP + "[execution]\nmax_members = 11\n")
        with self.assertRaisesRegex(SweepError, "12 members"):
            build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        spec = self.read(SWEEP + "[execution]\nmax_members = 12\n")
        self.assertEqual(len(build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
                             .members), 12)

    def test_progress(self):
        spec = self.read(self.big(100, 100, "[execution]\nmax_members = 20000\n"))
        seen = []
        plan = build_plan(spec, Path(self.tmp.name) / "out", "/bin/true",
                          progress=lambda done, total: seen.append((done, total)))
        self.assertEqual(seen, [(10000, 20000), (20000, 20000)])
        self.assertEqual(plan.members[-1].id, "s9999_r01")
        self.assertEqual(plan.members[-1].overrides[-2:], ["run.seed=6", "dem.threads=1"])

    def test_progress_of_the_check(self):
        import contextlib
        import io
        from sweep import cli
        plan = build_plan(self.read(self.big(5, 50)), Path(self.tmp.name) / "out", "/bin/true")
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            cli.check_settings(plan, plan.members)  # /bin/true accepts every setting
        self.assertEqual(buf.getvalue().splitlines(), ["sweep t: checked 100 of 250 settings",
                                                       "sweep t: checked 200 of 250 settings"])


class Extraction(unittest.TestCase):
    T = [0.0, 1.0, 2.0, 4.0]
    V = [0.0, 2.0, 1.0, 5.0]

    def q(self, **kw):
        base = dict(name="q", file="f.csv", column="v", time_column="time", unit="", kind="final")
        base.update(kw)
        return Quantity(**base)

    def value(self, **kw):
        return extract(self.q(**kw), self.T, self.V, "w", "m")

    def test_values(self):
        self.assertEqual(self.value(kind="final"), 5.0)
        self.assertEqual(self.value(kind="max"), 5.0)
        self.assertEqual(self.value(kind="min", window=(0.5, 3.0)), 1.0)
        self.assertEqual(self.value(kind="at", at=1.5), 1.5)   # (2 + 1) / 2
        self.assertEqual(self.value(kind="at", at=3.0), 3.0)   # 1 + (5 - 1) / 2
        self.assertEqual(self.value(kind="at", at=1.0), 2.0)
        self.assertEqual(self.value(kind="at", at=1.4, method="nearest"), 2.0)
        self.assertEqual(self.value(kind="at", at=1.5, method="nearest"), 2.0)  # tie: earlier
        # Trapezoid over [0, 4]: 1 + 1.5 + 6 = 8.5, / 4.
        self.assertEqual(self.value(kind="mean"), 8.5 / 4)
        # Over [0.5, 3]: ends interpolated (1 at 0.5, 3 at 3): 0.75 + 1.5 + 2 = 4.25, / 2.5.
        self.assertAlmostEqual(self.value(kind="mean", window=(0.5, 3.0)), 4.25 / 2.5,
                               delta=1e-15)
        t, v = self.value(kind="series", window=(1.0, 2.0))
        self.assertEqual((t, v), ([1.0, 2.0], [2.0, 1.0]))
        # last = 2.5: the window [1.5, 4] from the series' own end (1.5 at 1.5): 0.625 + 6.
        self.assertAlmostEqual(self.value(kind="mean", last=2.5), 6.625 / 2.5, delta=1e-15)
        self.assertEqual(self.value(kind="min", last=2.5), 1.0)
        self.assertEqual(self.value(kind="series", last=2.0), ([2.0, 4.0], [1.0, 5.0]))
        self.assertEqual(interpolate(self.T, self.V, -1.0), 0.0)
        # relative_to = 1.5: the value there, 1.5, is subtracted from every row first.
        self.assertEqual(self.value(kind="final", relative_to=1.5), 3.5)
        self.assertEqual(self.value(kind="at", at=3.0, relative_to=1.5), 1.5)
        self.assertEqual(self.value(kind="max", relative_to=1.0), 3.0)
        self.assertEqual(self.value(kind="mean", relative_to=0.0), 8.5 / 4)
        self.assertAlmostEqual(self.value(kind="mean", last=2.5, relative_to=1.5),
                               6.625 / 2.5 - 1.5, delta=1e-15)
        self.assertEqual(self.value(kind="series", window=(1.0, 2.0), relative_to=2.0),
                         ([1.0, 2.0], [1.0, 0.0]))

    def test_errors(self):
        with self.assertRaisesRegex(SweepError, "outside member m's series"):
            self.value(kind="at", at=5.0)
        with self.assertRaisesRegex(SweepError, "no row"):
            self.value(kind="max", window=(2.5, 3.5))
        with self.assertRaisesRegex(SweepError, "do not overlap"):
            self.value(kind="mean", window=(5.0, 6.0))
        with self.assertRaisesRegex(SweepError, "relative_to = 4.5 s is outside member m's"):
            self.value(kind="final", relative_to=4.5)


class Retries(unittest.TestCase):
    def test_classify(self):
        self.assertEqual(classify(0, False), "done")
        self.assertEqual(classify(1, False), "retry")
        self.assertEqual(classify(4, True), "retry")
        self.assertEqual(classify(137, False), "retry")
        self.assertEqual(classify("timeout", False), "retry")
        self.assertEqual(classify(2, False), "give_up")   # bad input repeats
        self.assertEqual(classify(2, True), "fresh")      # no valid checkpoint: start over
        self.assertEqual(classify(3, True), "give_up")    # a blow-up repeats
        self.assertEqual(classify(127, False), "give_up")  # no demfem_run to start
        self.assertEqual(describe_exit(137), "exit 137 (SIGKILL)")


class ExitStatus(unittest.TestCase):
    """The sweep's exit statuses are the C++ header's (exit_status.hpp), read, not copied."""

    def test_every_code_of_the_header_is_read(self):
        text = exit_status.HEADER.read_text(encoding="utf-8")
        defined = re.findall(r"\bkExit\w+\s*=\s*\d+", text)
        read = sum(len(table) for table in exit_status.CODES.values())
        self.assertGreater(read, 0)
        self.assertEqual(read, len(defined))
        self.assertEqual(set(exit_status.CODES), {"demfem", "demfem::protocol"})

    def test_the_python_names_are_the_headers(self):
        # A code added to the header needs its EXIT_ name here (and a decision in classify);
        # one added here only is not in the header.
        exported = {k: v for k, v in vars(exit_status).items() if k.startswith("EXIT_")}
        self.assertEqual(exported, {k: v[0] for k, v in exit_status.RUN_CODES.items()})
        # tools/ and the Python SDK (whose EXIT_ names come from the bindings of the header).
        root = exit_status.HEADER.parents[5]
        sources = [*(root / "tools").rglob("*.py"), *(root / "protocol" / "python").rglob("*.py")]
        for source in sources:
            copies = re.findall(r"^\s*EXIT_\w+\s*=\s*\d", source.read_text(encoding="utf-8"),
                                re.MULTILINE)
            self.assertEqual(copies, [], f"{source}: an exit status copied, not read")

    def test_the_descriptions_are_unchanged(self):
        self.assertEqual(describe_exit(1), "exit 1 (failed)")
        self.assertEqual(describe_exit(2), "exit 2 (bad input)")
        self.assertEqual(describe_exit(3), "exit 3 (blow-up)")
        self.assertEqual(describe_exit(4), "exit 4 (a solver kept dying)")
        self.assertEqual(describe_exit(127), "exit 127 (demfem_run could not be started)")
        self.assertEqual(describe_exit(5), "exit 5")
        self.assertEqual(exit_status.CODES["demfem::protocol"]["EXIT_COUPLER_DIED"][0], 2)

    def test_a_code_in_another_form_is_refused(self):
        good = "namespace demfem {\ninline constexpr int kExitFailed = 1;  ///< failed: x\n"
        self.assertEqual(exit_status.read_header(good, "h.hpp"),
                         {"demfem": {"EXIT_FAILED": (1, "failed")}})
        for bad in ("constexpr int kExitOdd = 9;", "inline constexpr int kExitOdd = 9;"):
            with self.assertRaisesRegex(exit_status.HeaderError, r"h\.hpp:3: .*kExitOdd"):
                exit_status.read_header(good + bad + "\n", "h.hpp")


class Slurm(unittest.TestCase):
    def test_array_spec(self):
        self.assertEqual(slurm.array_spec([5, 0, 1, 2, 7, 8]), "0-2,5,7-8")
        self.assertEqual(slurm.array_spec([3]), "3")

    def test_script(self):
        class P:
            name, output_dir = "beam", "/scratch/beam"
        text = slurm.script_text(P, Path("/scratch/beam/slurm/plan.json"), 4, True,
                                 SlurmOptions(partition="gpu", time="1:00:00", account="proj",
                                              options=["--exclusive"]))
        for line in ("#SBATCH --cpus-per-task=4", "#SBATCH --gres=gpu:1",
                     "#SBATCH --partition=gpu", "#SBATCH --time=1:00:00",
                     "#SBATCH --account=proj", "#SBATCH --exclusive",
                     "#SBATCH --output=/scratch/beam/slurm/logs/%A_%a.out",
                     "-m sweep --member-task /scratch/beam/slurm/plan.json "
                     "\"$SLURM_ARRAY_TASK_ID\"", "#SBATCH --signal=B:USR2@120"):
            self.assertIn(line, text)
        # A --signal of the user's replaces ours.
        text = slurm.script_text(P, Path("/p.json"), 1, False,
                                 SlurmOptions(options=["--signal=B:USR1@600"]))
        self.assertIn("#SBATCH --signal=B:USR1@600", text)
        self.assertNotIn("USR2", text)

    def test_checkpoint_request_forwarded(self):
        # The task's handler passes SIGUSR1/2 on to demfem_run (here a sleep, which the signal
        # ends: demfem_run would checkpoint); SIGUSR2 also means no further attempt.
        h = Handle()
        h.proc = subprocess.Popen(["sleep", "30"])
        h.forward(signal.SIGUSR1, False)
        self.assertEqual(h.proc.wait(timeout=10), -signal.SIGUSR1)
        self.assertFalse(h.stop.is_set())
        h.proc = subprocess.Popen(["sleep", "30"])
        h.forward(signal.SIGUSR2, True)
        self.assertEqual(h.proc.wait(timeout=10), -signal.SIGUSR2)
        self.assertTrue(h.stop.is_set())


# Run in a child process by SignalWhileStarting: a signal that reaches a Slurm task's handler
# (cli.member_task) while its main thread starts demfem_run.
_START_RACE = r"""
import os, signal, subprocess, sys, types
sys.path.insert(0, sys.argv[1])
from sweep import member
folder, sig = sys.argv[2], getattr(signal, sys.argv[3])
h = member.Handle()
signal.signal(sig, lambda s, f: h.forward(signal.SIGUSR2, True))
real = subprocess.Popen
def popen(*a, **kw):
    os.kill(os.getpid(), sig)  # the handler runs now, inside Handle.start, under its lock
    return real(*a, **kw)
subprocess.Popen = popen
stand_in = os.path.join(folder, "demfem_run")
with open(stand_in, "w") as f:
    f.write("#!/bin/sh\nexec sleep 60\n")
os.chmod(stand_in, 0o755)
plan = types.SimpleNamespace(demfem_run=stand_in, scene="s.toml", args=[], timeout=0)
run = member.RunUnit("", "s.toml", [], folder, "", folder)
code, _, _ = member._attempt(plan, run, 1, False, os.path.join(folder, "a.log"), h, None)
print(code, h.stop.is_set())
"""


class SignalWhileStarting(unittest.TestCase):
    """Issue 34, item 16: a Slurm task that got SIGUSR2 (or scancel's SIGTERM) while starting
    demfem_run deadlocked in its own signal handler (a non-re-entrant lock taken twice by the
    main thread) and hung until Slurm killed it; under load the window is wide. Now the
    signal is kept and sent to demfem_run as soon as it runs."""

    def test_signal_during_popen(self):
        tools = str(Path(__file__).resolve().parents[2] / "tools")
        for sig in ("SIGUSR2", "SIGTERM"):
            with tempfile.TemporaryDirectory() as d:
                try:
                    r = subprocess.run([sys.executable, "-c", _START_RACE, tools, d, sig],
                                       capture_output=True, text=True, timeout=120)
                except subprocess.TimeoutExpired:
                    self.fail(f"{sig} while starting demfem_run: the task hangs (deadlock)")
                self.assertEqual(r.returncode, 0, r.stderr)
                # The stand-in got the forwarded SIGUSR2 at once (not its 60 s sleep's end).
                self.assertEqual(r.stdout.split(), [str(128 + signal.SIGUSR2), "True"])


if __name__ == "__main__":
    unittest.main(verbosity=1)
