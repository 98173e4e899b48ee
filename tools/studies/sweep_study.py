"""What every study does with the sweep: a sweep file written from the study's settings, the
sweep run (tools/sweep, the same pool, retries, resume and records as `demfem sweep`), and
its members read back with their states and folders."""

from pathlib import Path

from sweep import records, status
from sweep.cli import main as sweep_main
from sweep.plan import load_plan
from sweep.scene_keys import toml_value


def sweep_file_text(name, scene, parameters, quantities, execution=None):
    """The TOML of a sweep: `parameters` [(name, {scene key: [values]})] (keys of one
    parameter zipped), `quantities` [{key: value}] as [[quantity]] tables, `execution`
    {key: value}. No [repetitions]: each setting runs once with the scene's own seed."""
    out = ["# Written by tools/studies: the study's settings as a sweep (docs/sweeps.md).",
           "[sweep]", f"scene = {toml_value(str(scene))}", f"name = {toml_value(name)}", ""]
    for pname, keys in parameters:
        out += ["[[parameter]]", f"name = {toml_value(pname)}", "[parameter.keys]"]
        out += [f"{toml_value(k)} = {toml_value(v)}" for k, v in keys.items()]
        out.append("")
    if execution:
        out.append("[execution]")
        out += [f"{k} = {toml_value(v)}" for k, v in execution.items()]
        out.append("")
    for q in quantities:
        out.append("[[quantity]]")
        out += [f"{k} = {toml_value(v)}" for k, v in q.items()]
        out.append("")
    return "\n".join(out)


def run_study_sweep(folder, name, text, demfem_run, extra=()):
    """Writes the sweep file <folder>/<name>.sweep.toml and runs it into <folder>/<name>
    (what is done already is skipped, as by `demfem sweep`); returns its exit status (1: a
    member failed, which a study of stability expects)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.sweep.toml"
    path.write_text(text)
    return sweep_main([str(path), "--output-dir", str(folder / name), "--demfem-run",
                       str(demfem_run), "--no-plots", *extra])


def members_of(folder, name):
    """[(member, state, record)] of the sweep in <folder>/<name>, in the plan's order."""
    plan = load_plan(Path(folder) / name / "plan.json")
    return [(m, s, r) for (m, s, r, _) in status.gather(plan)]


def last_exit(record):
    """The exit status of the member's last attempt (None before any)."""
    attempts = record.get("attempts") or []
    return attempts[-1].get("exit") if attempts else None


def last_message(member, record):
    """The last line of the member's last attempt log (what demfem_run said at its end)."""
    attempts = record.get("attempts") or []
    if not attempts:
        return ""
    try:
        lines = (Path(member.folder) / attempts[-1]["log"]).read_text(
            errors="replace").strip().splitlines()
    except OSError:
        return ""
    return (lines[-1] if lines else "")[:300]


DONE = records.DONE
