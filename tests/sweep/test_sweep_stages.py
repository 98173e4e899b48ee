#!/usr/bin/python3
"""ctest: chained stages of a sweep (docs/sweeps.md, "Chained stages") without solvers: the
[[stage]] tables read strictly (messages with file, line and key), the plan of a chain (each
stage's overrides, folder, checkpoints; the member's threads), and a member run through a
stand-in for demfem_run: the stages one after the other, a failing stage ending the member
there, and the next run going on at that stage without running the done ones again."""

import json
import os
import unittest
from pathlib import Path

from sweep_testing import sweep_file_case, write  # first: it puts tools/ on sys.path

from sweep import member as member_mod
from sweep.plan import build_plan
from sweep.sweep_file import SweepError

BED = """
[run]
end_time = 0.01
[dem]
dt = 2e-6
threads = 2
[[dem.insert]]
mass = 30.0
[dem.output]
state = true
"""

LOAD = """
[run]
end_time = 0.01
[dem]
dt = 2e-6
[dem.load]
file = "data/bed.csv"
[fem]
dt = 1e-4
[checkpoint]
every_steps = 10
"""

CHAIN = """\
[sweep]
name = "chain"

[[stage]]
name = "bed"
scene = "bed.toml"
pass = ["run.seed", "dem.insert"]

[[stage]]
name = "load"
scene = "load.toml"
pass = ["fem"]
set = ['dem.load.file="{bed}/dem_state.h5"', "dem.load.history=false"]

[[parameter]]
name = "mass"
[parameter.keys]
"dem.insert[0].mass" = [10.0, 20.0]

[[parameter]]
name = "dt"
[parameter.keys]
"fem.dt" = [1e-4, 2e-4]

[repetitions]
count = 2
first_seed = 3

[[quantity]]
name = "q"
file = "coupling.csv"
column = "x"
reduce = "max"

[[quantity]]
name = "bed_q"
stage = "bed"
file = "coupling.csv"
column = "x"
reduce = "final"
"""

# Stands in for demfem_run: appends its command line to $CALLS, writes a finished run.json
# into its --output-dir, and exits 1 for the stage named in $FAIL_STAGE while $FAIL_FILE exists.
STAND_IN = """\
#!/usr/bin/python3
import json, os, sys
args = sys.argv[1:]
out = args[args.index("--output-dir") + 1]
with open(os.environ["CALLS"], "a") as f:
    f.write(json.dumps({"cwd": os.getcwd(), "args": args}) + "\\n")
if os.path.basename(out) == os.environ.get("FAIL_STAGE") and os.path.exists(os.environ["FAIL_FILE"]):
    sys.exit(1)
with open(os.path.join(out, "run.json"), "w") as f:
    json.dump({"status": "completed", "exit_code": 0}, f)
"""


class Stages(sweep_file_case({"bed.toml": BED, "load.toml": LOAD})):
    def test_plan_of_a_chain(self):
        spec = self.read(CHAIN)
        self.assertEqual([s.name for s in spec.stages], ["bed", "load"])
        self.assertEqual(spec.scene.name, "load.toml")  # the last stage: the member's result
        self.assertEqual([q.stage for q in spec.quantities], ["load", "bed"])
        out = Path(self.tmp.name) / "out"
        plan = build_plan(spec, out, "/bin/true")
        self.assertEqual([s["name"] for s in plan.stages], ["bed", "load"])
        self.assertEqual(len(plan.members), 2 * 2 * 2)
        m = plan.members[5]  # setting 2 = (mass 20, fem.dt 1e-4), repetition 1: seed 4
        self.assertEqual((m.id, m.seed), ("s02_r01", 4))
        self.assertEqual(m.overrides, ["dem.insert[0].mass=20.0", "fem.dt=0.0001", "run.seed=4"])
        folder = out.resolve() / "members" / "s02_r01"
        bed, load = m.stages
        # The bed gets the seed and the mass (its pass list), keeps its own dem.threads (2).
        self.assertEqual(bed, {"name": "bed", "overrides": ["dem.insert[0].mass=20.0",
                                                            "run.seed=4"],
                               "checkpoints": "", "folder": str(folder / "bed")})
        # The load case gets fem.dt, its own set with {bed} as the bed's folder, and
        # execution.threads (1) for its dem.threads = 0.
        self.assertEqual(load["overrides"], [
            "fem.dt=0.0001", f'dem.load.file="{folder / "bed"}/dem_state.h5"',
            "dem.load.history=false", "dem.threads=1"])
        self.assertEqual((load["checkpoints"], load["folder"]),
                         ("checkpoints", str(folder / "load")))
        self.assertEqual((m.threads, m.gpu), (2, False))  # the most of its stages

    def test_a_plain_sweep_has_no_stages(self):
        spec = self.read(CHAIN.replace('name = "chain"', 'name = "plain"\nscene = "bed.toml"')
                         .split("[[stage]]")[0] + "[repetitions]\ncount = 2\n")
        plan = build_plan(spec, Path(self.tmp.name) / "out", "/bin/true")
        self.assertEqual((spec.stages, plan.stages), ([], []))
        self.assertEqual(plan.members[1].stages, [])
        self.assertEqual(plan.members[1].overrides, ["run.seed=2"])  # dem.threads = 2: kept

    def test_refusals_name_file_line_key(self):
        f = str(Path(self.tmp.name) / "s.toml")
        self.refused(CHAIN.replace('name = "chain"', 'name = "chain"\nscene = "bed.toml"'),
                     f"{f}:3: key 'sweep.scene'", "each stage names its scene")
        self.refused(CHAIN.replace("{bed}", "{load}"), f"{f}:13: key 'stage[1].set'",
                     "{load} is not an earlier stage", "bed")
        self.refused(CHAIN.replace('name = "load"', 'name = "bed"'), "key 'stage[1].name'",
                     "names two stages")
        self.refused(CHAIN.replace('name = "load"', 'name = "members"'), "key 'stage[1].name'",
                     "not 'members'")
        self.refused(CHAIN.replace('pass = ["fem"]', "pass = []"),
                     "key 'parameter[1].keys.\"fem.dt\"'", "'fem.dt' reaches no stage")
        self.refused(CHAIN.replace('pass = ["fem"]', 'pass = ["fem", "dem.insert"]'),
                     "key 'parameter[0].keys.\"dem.insert[0].mass\"'", "stage 'load'")
        self.refused(CHAIN.replace('pass = ["run.seed", "dem.insert"]', 'pass = ["dem.insert"]'),
                     f"{f}:25: key 'repetitions.key'", "'run.seed' reaches no stage")
        self.refused(CHAIN.replace('"dem.load.history=false"', '"dem.nothing.x=1"'),
                     "key 'stage[1].set'", "dem.nothing.x=1")
        self.refused(CHAIN.replace('"dem.load.history=false"', '"dem.load.history=no"'),
                     "key 'stage[1].set'", "not a TOML value")
        self.refused(CHAIN.replace('stage = "bed"', 'stage = "pour"'),
                     "key 'quantity[1].stage'", '"bed", "load"')
        plain = CHAIN.replace('name = "chain"', 'name = "p"\nscene = "bed.toml"')
        plain = plain.split("[[stage]]")[0] + "[[quantity]]\nname = \"q\"\nfile = \"a.csv\"\n" \
            "column = \"x\"\nreduce = \"max\"\nstage = \"bed\"\n"
        self.refused(plain, "key 'quantity[0].stage'", "needs [[stage]]")

    def test_member_runs_its_stages_in_order_and_resumes_at_the_failed_one(self):
        stand_in = write(self.tmp.name, "demfem_run", STAND_IN)
        os.chmod(stand_in, 0o755)
        calls, fail_file = Path(self.tmp.name) / "calls", Path(self.tmp.name) / "fail"
        os.environ.update(CALLS=str(calls), FAIL_STAGE="load", FAIL_FILE=str(fail_file))
        plan = build_plan(self.read(CHAIN), Path(self.tmp.name) / "out", str(stand_in))
        plan.max_retries = 1
        m = plan.members[0]
        fail_file.write_text("")
        rec = member_mod.run_member(plan, m, log=lambda *a: None)
        seen = [json.loads(x) for x in calls.read_text().splitlines()]
        # bed once, then load twice (1 + max_retries), each in the member's folder
        self.assertEqual([Path(c["args"][c["args"].index("--output-dir") + 1]).name
                          for c in seen], ["bed", "load", "load"])
        self.assertTrue(all(c["cwd"] == m.folder for c in seen))
        self.assertEqual(seen[0]["args"][0], str(Path(self.tmp.name) / "bed.toml"))
        self.assertEqual((rec["state"], rec["stages"]["bed"]["state"],
                          rec["stages"]["load"]["state"]), ("failed", "done", "failed"))
        self.assertTrue(rec["reason"].startswith("stage load: failed 2 times in a row: exit 1"),
                        rec["reason"])
        self.assertEqual([a["log"] for a in rec["attempts"]],
                         ["bed/attempt-1.log", "load/attempt-1.log", "load/attempt-2.log"])
        # Run again without the fault: the bed is not run again, the load goes on.
        fail_file.unlink()
        calls.unlink()
        rec = member_mod.run_member(plan, m, log=lambda *a: None)
        seen = [json.loads(x) for x in calls.read_text().splitlines()]
        self.assertEqual(len(seen), 1)
        self.assertEqual(Path(seen[0]["args"][seen[0]["args"].index("--output-dir") + 1]).name,
                         "load")
        self.assertEqual((rec["state"], rec["stages"]["load"]["state"]), ("done", "done"))
        self.assertEqual(rec["attempts"][-1]["log"], "load/attempt-3.log")
        self.assertAlmostEqual(rec["run_time"], rec["stages"]["bed"]["run_time"] +
                               rec["stages"]["load"]["run_time"], places=12)
        on_disk = json.loads((Path(m.folder) / "status.json").read_text())
        self.assertEqual(on_disk["state"], "done")
        # member.json records each stage's scene hash and overrides: another set is refused.
        ident = json.loads((Path(m.folder) / "member.json").read_text())
        self.assertEqual([s["name"] for s in ident["stages"]], ["bed", "load"])
        changed = build_plan(self.read(CHAIN.replace("history=false", "history=true")),
                             Path(self.tmp.name) / "out", str(stand_in))
        with self.assertRaises(SweepError) as c:
            member_mod.run_member(changed, changed.members[0], log=lambda *a: None)
        self.assertIn("other stages", str(c.exception))

    def test_a_failing_first_stage_ends_the_member_and_frees_its_cores(self):
        stand_in = write(self.tmp.name, "demfem_run", STAND_IN)
        os.chmod(stand_in, 0o755)
        calls, fail_file = Path(self.tmp.name) / "calls", Path(self.tmp.name) / "fail"
        os.environ.update(CALLS=str(calls), FAIL_STAGE="bed", FAIL_FILE=str(fail_file))
        fail_file.write_text("")
        plan = build_plan(self.read(CHAIN), Path(self.tmp.name) / "out", str(stand_in))
        plan.max_retries = 0
        settled = []
        rec = member_mod.run_member(plan, plan.members[0], log=lambda *a: None,
                                    settled=lambda: settled.append(1))
        self.assertEqual(len(calls.read_text().splitlines()), 1)  # the load never started
        self.assertEqual((rec["state"], rec["stages"]["load"]["state"]), ("failed", "new"))
        self.assertEqual(settled, [1])  # the pool hears once that the member's cores are free


if __name__ == "__main__":
    unittest.main(verbosity=2)
