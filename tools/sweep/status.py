"""The state of every member, the same for both modes: the member folders' records, and for
members submitted to Slurm what squeue (queued, running) and sacct or scontrol (how a task
ended) say."""

import sys
from collections import Counter

from sweep import records, slurm
from sweep.sweep_file import SweepError


def gather(plan):
    """[(member, state, record, detail)]: state one of done, failed, running, queued,
    interrupted, lost (a Slurm task that ended without a final record), new."""
    jobs = slurm.load_jobs(plan)
    latest = slurm.last_job_of(jobs)
    try:
        active = slurm.active_tasks(sorted({j["job_id"] for j in jobs})) if jobs else {}
    except SweepError as e:
        # The sweep was submitted to Slurm, but Slurm cannot be asked from here: the member
        # records are all there is (a queued task's member shows as not started).
        print(f"demfem sweep: warning: {e}; the states below come from the member folders "
              "only", file=sys.stderr)
        jobs, latest, active = [], {}, {}
    ended = None
    out = []
    for m in plan.members:
        state, rec = records.member_state(m.folder)
        detail = ""
        job = latest.get(m.index)
        if state not in (records.DONE,) and job is not None:
            key = (job["job_id"], m.index)
            if key in active:
                state = active[key]
                detail = f"Slurm job {job['job_id']}_{m.index}"
            elif state != records.FAILED and (
                    (rec or {}).get("state") in ("running", None)
                    or (rec or {}).get("updated", 0) < job["submitted"]):
                # Its task ended, and no final record was written after the submission.
                if ended is None:
                    ended = slurm.ended_tasks(sorted({j["job_id"] for j in jobs}))
                log = slurm.slurm_dir(plan) / "logs" / f"{job['job_id']}_{m.index}.out"
                detail = (f"Slurm job {job['job_id']}_{m.index} ended without finishing the "
                          f"member ({ended.get(key, 'state unknown')}); log {log}")
                state = "lost"
            elif state == "interrupted":
                if ended is None:
                    ended = slurm.ended_tasks(sorted({j["job_id"] for j in jobs}))
                if key in ended:
                    detail = f"Slurm: {ended[key]}"
        out.append((m, state, rec or {}, detail))
    return out


def counts(states):
    c = Counter(s for (_, s, _, _) in states)
    return c


def report(plan, states, out_write, header=True):
    c = counts(states)
    order = ("done", "running", "queued", "failed", "lost", "interrupted", "new")
    names = {"new": "not started"}
    if header:
        out_write(f"sweep {plan.name}: {len(states)} members: " +
                  ", ".join(f"{c.get(s, 0)} {names.get(s, s)}" for s in order) +
                  f"  ({plan.output_dir})")
    for m, state, rec, detail in states:
        if state in (records.DONE, "new", "queued"):
            continue  # counted above; a line each would bury the ones that need a look
        attempts = len(rec.get("attempts", []))
        text = f"  {m.id}: {state}"
        if rec.get("stages") and rec.get("stage"):  # a chain: where it stands
            text += f" at stage {rec['stage']} (" + ", ".join(
                f"{ms['name']} {(rec['stages'].get(ms['name']) or {}).get('state', 'new')}"
                for ms in m.stages) + ")"
        if attempts:
            last = rec["attempts"][-1]
            text += f", {attempts} attempt(s), last exit {last.get('exit')}"
            text += f", log {m.folder}/{last.get('log')}"
        if rec.get("reason"):
            text += f"; {rec['reason']}"
        if detail:
            text += f"; {detail}"
        out_write(text)
