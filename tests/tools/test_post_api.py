"""ctest: the post-processing API (tools/demfem_post, docs/postprocessing.md).

usage: test_post_api.py units
       test_post_api.py beam|sheet|sleeper|tutorial DEMFEM_RUN

units: the CSV reader, the XDMF reader, missing modules, the run folder, the scene with
overrides, exit names and plots on made-up files. beam, sheet, sleeper: run
cases/beam_fixed_ci.toml, cases/sheet_ci.toml or cases/sleeper_ci.toml (with their prepare
and post steps) in a temporary folder and get the numbers of the reports those runs write
(the beam check table demfem_run prints, sheet_report.json, sleeper_report.json) out of the
output folder through the API: the raw series as numpy arrays, the statistics with numpy, so
that a wrong reader or a wrong column cannot agree with the report by construction; and the
fields (XDMF + HDF5) against the series. tutorial: docs/postprocessing.md's tutorial runs
and its numbers hold. Exit 77 (skipped) where numpy is missing, or
matplotlib for the cases whose post steps plot. With tools/ on PYTHONPATH."""

import json
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2]
FAILURES = []


def check(ok, what):
    print(("ok:   " if ok else "FAIL: ") + what)
    if not ok:
        FAILURES.append(what)


def close(a, b, rel=1e-12):
    """a and b agree to round-off (numpy's pairwise sums against the reports' sequential
    ones); exact when b is 0."""
    return abs(a - b) <= rel * max(abs(a), abs(b))


def skip(why):
    print(f"skipped: {why}")
    sys.exit(77)


try:
    import numpy as np
except ImportError:
    skip(f"numpy is missing in {sys.executable} (Debian: python3-numpy)")

import demfem_post  # noqa: E402
from demfem_post.needs import MissingModule  # noqa: E402


def raises(exc, fn, *words):
    """fn() raises exc, with every one of `words` in its message."""
    try:
        fn()
    except exc as e:
        text = e.args[0] if e.args else str(e)
        return all(w in text for w in words)
    return False


def write(path, text):
    Path(path).write_text(text)
    return str(path)


# --- units --------------------------------------------------------------------------------
def units_csv(d):
    # the last row cut short, as a run killed while writing it leaves it
    p = write(d / "sensor_outflow.csv",
              " time, mass_flow ,mass_crossed\n0.1,1.5,0\n0.2,2.5,0.2\n0.3,")
    t = demfem_post.read_csv(p)
    check(t.header == ["time", "mass_flow", "mass_crossed"], "header names are stripped")
    check(t.rows == 2 and t.column("mass_flow") == [1.5, 2.5], "an incomplete last row is skipped")
    check(isinstance(t["time"], np.ndarray) and t["time"].tolist() == [0.1, 0.2],
          "columns are numpy arrays with the file's values")
    check("mass_flow" in t and "x" not in t and list(t) == t.header, "a mapping of the columns")
    check(raises(KeyError, lambda: t["x"], p, "no column 'x'", "time, mass_flow"),
          "an unknown column names the file and its columns")
    check(raises(ValueError, lambda: demfem_post.read_csv(p, incomplete_rows="error"), p + ":4:"),
          "incomplete rows refused on request, naming file and line")
    q = write(d / "text.csv", "time,a\n0.1,x\n")
    check(raises(ValueError, lambda: demfem_post.read_csv(q), q + ":2:", "'a'", "'x'"),
          "a field that is not a number names file, line and column")
    check(math.isnan(demfem_post.read_csv(q, text_as_nan=True).column("a")[0]),
          "text_as_nan reads it as NaN")
    e = write(d / "empty.csv", "time,a\n")
    check(raises(ValueError, lambda: demfem_post.read_csv(e), e, "no data rows"),
          "a header without rows is refused")
    check(raises(FileNotFoundError, lambda: demfem_post.read_csv(d / "none.csv"), "none.csv"),
          "a missing file is named")
    try:
        import pandas  # noqa: F401
        check(t.frame()["mass_flow"].tolist() == [1.5, 2.5], "frame() is a pandas DataFrame")
    except ImportError:
        check(raises(MissingModule, t.frame, "python3-pandas", sys.executable),
              "frame() without pandas names the package and the interpreter")


def units_needs():
    try:
        demfem_post.need("no_such_module_of_demfem", "python3-nothing")
        check(False, "a missing module is refused")
    except MissingModule as e:
        check(all(w in str(e) for w in ("no_such_module_of_demfem", sys.executable,
                                         "python3-nothing", "/usr/bin/python3")),
              "a missing module names itself, this interpreter, the package and the one to use")
    script = ("from demfem_post.needs import need_or_exit\n"
              "need_or_exit('tool.py', 'no_such_module_of_demfem', 'python3-x', 'pvpython')")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    check(r.returncode == 2 and r.stderr.startswith("tool.py: no_such_module_of_demfem is missing")
          and "pvpython" in r.stderr, "a script without a module it needs says so and exits 2")


def units_fields(d):
    from demfem_post.fields import FieldSeries
    bad = write(d / "bad.xdmf", "<Xdmf><Domain>")
    check(raises(ValueError, lambda: FieldSeries(bad), bad, "not XDMF"), "broken XML is named")
    flat = write(d / "flat.xdmf", '<Xdmf><Domain><Grid Name="g"/></Domain></Xdmf>')
    check(raises(ValueError, lambda: FieldSeries(flat), flat, "no temporal collection"),
          "an XDMF file without snapshots is named")
    item = '<DataItem Dimensions="2 3" Format="HDF">{}:/{}</DataItem>'
    grid = ('<Grid Name="step_{k}" GridType="Uniform"><Time Value="{t}"/>'
            '<Topology TopologyType="Polyvertex">' + item.format("p_{k}.h5", "vertex") +
            '</Topology><Geometry GeometryType="XYZ">' + item.format("p_{k}.h5", "position") +
            '</Geometry><Attribute Name="radius" Center="Node">' +
            item.format("p_{k}.h5", "radius") + '</Attribute></Grid>')
    snapshots = "".join(grid.format(k=k, t=0.05 * k) for k in range(3))
    path = write(d / "particles.xdmf", '<Xdmf><Domain><Grid Name="particles" GridType='
                 f'"Collection" CollectionType="Temporal">{snapshots}</Grid></Domain></Xdmf>')
    fields = FieldSeries(path)
    check(fields.times == [0.0, 0.05, 0.1] and len(fields) == 3, "the snapshots' times")
    f = fields.at(0.06)
    check(f.name == "step_1" and f.time == 0.05 and f.cell_type == "Polyvertex" and
          list(f.point_data) == ["radius"] and list(f.cell_data) == [],
          "the snapshot nearest to a time, its topology and data names")
    check(raises(KeyError, lambda: f["mass"], "no data 'mass'", "radius"),
          "an unknown datum names the ones there are")
    check(raises(FileNotFoundError, lambda: f.points, str(d / "p_1.h5")),
          "a missing HDF5 file is named")


def units_help(d):
    """Every script in tools/ answers --help with its usage (exit 0) and writes nothing; a
    ParaView script without ParaView's Python names pvpython instead (exit 2)."""
    cwd = d / "help"
    cwd.mkdir()
    for script in sorted((SOURCE / "tools").glob("*.py")):
        r = subprocess.run([sys.executable, str(script), "--help"], cwd=cwd, capture_output=True,
                           text=True, env=dict(os.environ, PYTHONPATH=str(SOURCE / "tools")))
        ok = (r.returncode == 0 and "usage" in (r.stdout + r.stderr).lower()
              or r.returncode == 2 and "pvpython" in r.stderr)
        check(ok and not any(cwd.iterdir()), f"{script.name} --help: its usage, nothing written")


def units_run(d):
    out = d / "out"
    out.mkdir()
    scene = write(d / "scene.toml", '[run]\nname = "s"\nend_time = 1.0\n[[dem.pairs]]\n'
                  'friction = 0.5\n')
    write(out / "run.json", json.dumps({"status": "failed", "exit_code": 3, "scene": scene,
                                        "overrides": ["run.end_time=2.5"]}))
    write(out / "coupling.csv", "step,time,force_sum_z\n0,0.1,-1\n1,0.2,-3\n")
    write(out / "sensor_base.csv", "time,fz\n0.1,4\n")
    write(out / "sleeper_report.json", '{"hold": {"base_reaction_N": 12.5}}')
    run = demfem_post.open(out)
    check(run.status == "failed" and run.exit_description == "exit 3 (blow-up)",
          "run.json's status and the exit code's name (tools/sweep/exit_status.py)")
    sc = run.scene(["dem.pairs[0].friction=0.7"])
    check(sc["run"]["end_time"] == 2.5 and sc["dem"]["pairs"][0]["friction"] == 0.7,
          "the scene with the run's recorded overrides and further ones")
    check(raises(ValueError, lambda: run.scene(["nope.x=1"]), scene, "nope.x"),
          "an override under a table the scene lacks names the scene and the key")
    check(run.series_names() == ["coupling", "sensor_base"] and list(run.sensors) == ["base"],
          "the folder's series and sensors")
    check(run.coupling["force_sum_z"].min() == -3.0 and run.sensor("base").column("fz") == [4.0],
          "series by property and by name")
    check(run.report("sleeper")["hold"]["base_reaction_N"] == 12.5, "a post tool's report")
    check(raises(FileNotFoundError, lambda: run.report("sheet"), "sheet_report.json"),
          "a missing report is named")
    check(raises(FileNotFoundError, lambda: run.monitor, "fem_monitor.csv"),
          "a missing series is named")
    check(raises(FileNotFoundError, lambda: demfem_post.open(d / "nowhere"), "nowhere"),
          "a missing folder is named")
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("matplotlib is missing: the plot is not checked")
        return
    png = str(d / "force.png")
    run.plot("coupling", "force_sum_z", out=png)
    check(Path(png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", "a one-line plot writes a PNG")
    check(raises(KeyError, lambda: run.plot("coupling", "nope"), "no column 'nope'"),
          "a plot of an unknown column is refused before drawing")


# --- real runs ----------------------------------------------------------------------------
def run_case(scene, demfem_run, work):
    """demfem_run on cases/<scene> in `work` (prepare and post steps included): its stdout."""
    r = subprocess.run([demfem_run, "--bin-dir", os.path.dirname(demfem_run),
                        str(SOURCE / "cases" / scene), "--quiet"],
                       cwd=work, capture_output=True, text=True)
    print(r.stdout[-3000:], r.stderr[-3000:], sep="\n")
    if r.returncode != 0 and "matplotlib" in r.stderr:
        skip("the case's post step needs matplotlib (Debian: python3-matplotlib)")
    check(r.returncode == 0, f"demfem_run {scene} exited {r.returncode}")
    if r.returncode != 0:
        sys.exit(1)
    return r.stdout


def beam(demfem_run, work):
    text = run_case("beam_fixed_ci.toml", demfem_run, work)
    run = demfem_post.open(Path(work) / "out" / "beam_fixed_ci")
    check(run.status == "completed", "run.json: completed")
    bc = run.beam_check
    coupled, fem, analytical = bc["coupled"][0], bc["fem_pressure"][0], bc["analytical"][0]
    printed = re.search(r"coupled \(DEM load\)\s+(\S+)\s+\S+ % vs pure FEM, (\S+) % vs analytical",
                        text)
    check(printed is not None, "the beam check table is printed")
    check(printed.group(1) == f"{coupled:.9e}", f"coupled deflection {printed.group(1)} m")
    check(printed.group(2) == f"{100 * (coupled - analytical) / analytical:+.4f}",
          f"{printed.group(2)} % against the analytical deflection")
    check(f"{fem:.9e}" in text and f"{analytical:.9e}" in text,
          "pure-FEM and analytical deflections")
    # the analytical value again, from the scene's [coupling.beam_check] (eq. 4.1-4.3)
    b = run.scene()["coupling"]["beam_check"]
    w = bc["pressure_load"][0] / b["length"]
    ei = b["youngs_modulus"] * b["width"] * b["height"] ** 3 / 12
    check(close(-w * b["length"] ** 4 / (384 * ei), analytical),
          "w L^4 / (384 E I) from the run's scene")
    # the load reached the beam: the last coupling step's interface force is the load
    check(f"{-run.coupling['force_sum_z'][-1]:.9g}" == f"{bc['coupled_load'][0]:.9g}",
          "coupling.csv's last force_sum_z is the beam check's load")
    # the FEM field (fem.xdmf + HDF5) at the end: the largest nodal displacement is
    # fem_series.csv's, the node at the probe point moved by the coupled deflection
    fem = run.fem(run.coupling["time"][-1])
    u = fem["displacement"]
    check(fem.cell_type == "Hexahedron" and fem.cells.shape == (80, 8) and
          fem.points.shape == (189, 3), "the 20 x 2 x 2 hex8 mesh: 80 elements, 189 nodes")
    check(np.linalg.norm(u, axis=1).max() == run.fem_series["max_displacement"][-1],
          "largest displacement of the field = fem_series.csv's")
    probe = np.argmin(np.linalg.norm(fem.points - b["probe"], axis=1))
    # the beam check takes position - reference position (0.1 m): round-off of 1e-17 m
    check(close(u[probe, 2], coupled, rel=1e-9),
          "the probe node's uz in the field = the beam check's")


def tutorial(demfem_run, work):
    """docs/postprocessing.md's tutorial: its Python blocks run as written on the two beam
    runs, and the numbers it states are the runs' (a tutorial that no longer holds fails)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        skip("the tutorial draws plots: matplotlib is missing (Debian: python3-matplotlib)")
    run_case("beam_fixed_ci.toml", demfem_run, work)
    run_case("beam_dynamic_ci.toml", demfem_run, work)
    page = (SOURCE / "docs" / "postprocessing.md").read_text()
    section = page[page.index("## Tutorial"):page.index("## API reference")]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    check(len(blocks) == 3, "the tutorial has its three Python blocks")
    os.chdir(work)  # the tutorial's paths are relative to where demfem run was started
    namespace = {}
    for code in blocks:
        exec(compile(code, "docs/postprocessing.md", "exec"), namespace)
    check(os.path.isfile("force.png") and os.path.isfile("deflection.png"), "its two plots")
    fixed = demfem_post.open("out/beam_fixed_ci")
    bc, fem = fixed.beam_check, fixed.fem(0.008)
    stated = {  # each number as the page states it, and the value it stands for
        "-7.889088959e-07": f"{bc['coupled'][0]:.9e}",
        "-7.445089286e-07": f"{bc['analytical'][0]:.9e}",
        "+5.96 %": f"{100 * (bc['coupled'][0] / bc['analytical'][0] - 1):+.2f} %",
        "500.31 N": f"{-fixed.coupling['force_sum_z'][-1]:.2f} N",
        "(189, 3) nodes, (80, 8)": f"{fem.points.shape} nodes, {fem.cells.shape}",
        "-7.969e-07 m": f"{fem['displacement'][:, 2].min():.3e} m",
        "97695 Pa": f"{fem.cell_data['von_mises'].max():.0f} Pa",
    }
    dynamic = demfem_post.open("out/beam_dynamic_ci").coupling
    u, t = dynamic["fem_max_displacement"], dynamic["time"]
    stated.update({
        "1.396e-06 m at t = 1.3 ms": f"{u.max():.3e} m at t = {1e3 * t[u.argmax()]:.1f} ms",
        "6.58e-07 m at 5 ms": f"{u[-1]:.2e} m at {1e3 * t[-1]:.0f} ms",
        "(50 coupling steps)": f"({dynamic.rows} coupling steps)",
    })
    static = fixed.fem_series["max_displacement"][-1]
    first = u.argmax()
    second = first + 1 + int(np.argmax(np.diff(u[first:]) > 0))  # past the trough, rising
    second += int(np.argmax(np.diff(u[second:]) < 0))            # the top of that rise
    stated.update({
        "1.75 times": f"{u.max() / static:.2f} times",
        "(7.97e-7 m,": f"({static:.2e} m,".replace("e-07", "e-7"),
        "(the second peak: t = 3.9 ms)": f"(the second peak: t = {1e3 * t[second]:.1f} ms)",
        "period of about 2.6 ms": f"period of about {1e3 * (t[second] - t[first]):.1f} ms",
    })
    for text, value in stated.items():
        check(text in section and text == value, f"the tutorial's {text} (the run: {value})")


def window_mask(t, lo, hi):
    return (t >= lo) & (t <= hi)


def sheet(demfem_run, work):
    run_case("sheet_ci.toml", demfem_run, work)
    check_sheet(demfem_post.open(Path(work) / "out" / "sheet_ci"))


def check_sheet(run):
    """tools/sheet_report.py's key figures against the run's series."""
    rep = run.report("sheet")
    flow = run.sensor("outflow")
    t, rate, mass = flow["time"], flow["mass_flow"], flow["mass_crossed"]
    i = int(np.argmax(rate))
    check(rep["mass_flow"]["peak"] == {"time": t[i], "rate": rate[i]}, "peak mass flow")
    check(rep["mass_flow"]["final_mass"] == mass[-1] and rep["mass_flow"]["end_time"] == t[-1],
          "mass crossed by the end")
    s = rep["mass_flow"]["steady"]
    w = rate[window_mask(t, s["from"], s["to"])]
    check(close(s["mean"], w.mean()) and close(s["std"], w.std()) and s["samples"] == w.size
          and s["min"] == w.min() and s["max"] == w.max(), "steady mass flow: mean, sd, range")
    mon = run.monitor
    mt, uz, fz = mon["time"], mon[rep["probe"] + "_uz"], mon["force_z"]
    j = int(np.argmin(uz))
    check(rep["deflection"]["peak"] == {"time": mt[j], "uz": uz[j]}, "peak deflection")
    d = rep["deflection"]["steady"]
    dw = uz[window_mask(mt, d["from"], d["to"])]
    check(close(d["mean"], dw.mean()) and close(d["std"], dw.std()), "steady deflection")
    check(rep["force_z"]["min"] == fz.min(), "most downward force on the sheet")
    check(close(rep["force_z"]["steady_mean"], fz[window_mask(mt, d["from"], d["to"])].mean()),
          "mean force over the steady window")
    # the fields at the end: the grains below the sensor's plane are the mass that crossed
    # it, the FEM node at the probe moved as the monitor says, the walls are the scene's
    sc = run.scene()
    plane = next(x for x in sc["dem"]["sensors"] if x["name"] == "outflow")["point"][2]
    grains = run.particles(t[-1])
    check(grains.shapes is None and close(grains["mass"][grains.points[:, 2] < plane].sum(),
                                          mass[-1]), "mass of the grains below the plane")
    page = (SOURCE / "docs" / "postprocessing.md").read_text()
    check(page.count(f"# {mass[-1]:.4f} kg") == 2, "docs/postprocessing.md's example of it")
    fem = run.fem(mt[-1])
    point = next(x for x in sc["fem"]["monitor"]["probes"] if x["name"] == rep["probe"])
    node = np.argmin(np.linalg.norm(fem.points - point["point"], axis=1))
    check(fem.time == round(mt[-1], 9) and fem["displacement"][node, 2] == uz[-1],
          "the probe node's uz in the FEM field = the monitor's")
    check(list(run.walls(mt[-1])) == [w["name"] for w in sc["dem"]["walls"]],
          "the walls, by name, in the scene's order")
    txt = Path(run.file("sheet_report.txt")).read_text()
    check(f"peak {rate[i]:.3f} kg/s at t = {t[i]:.3f} s" in txt and
          f"peak {1e3 * uz[j]:.2f} mm at t = {mt[j]:.3f} s" in txt, "the text report's peaks")


def sleeper(demfem_run, work):
    run_case("sleeper_ci.toml", demfem_run, work)
    check_sleeper(demfem_post.open(Path(work) / "out" / "sleeper_ci"))


def check_sleeper(run):
    """tools/sleeper_report.py's key figures against the run's series and scene."""
    rep = run.report("sleeper")
    mon = run.monitor
    t = mon["time"]
    probes = sorted(h[:-3] for h in mon if re.fullmatch(r"b\w+_uz", h))
    check(rep["probes"] == probes and rep["final_time"] == t[-1], "bottom probes, last time")
    settle = 1e3 * np.mean([mon[p + "_uz"] for p in probes], axis=0)  # mm
    check(close(rep["settlement_final_mm"], settle[-1]) and
          close(rep["settlement_min_mm"], settle.min()), "final and lowest settlement")
    if "max_principal_strain" in rep:
        check(rep["max_principal_strain"] == run.fem_series["max_principal_strain"].max(),
              "largest principal strain (fem_series.csv)")
    for label, g in rep.get("strain", {}).items():
        e = (mon[f"sg_{label}_1_ux"] - mon[f"sg_{label}_0_ux"]) / (g["x1"] - g["x0"])
        check(close(g["final"], e[-1]) and close(g["max"], e.max()) and close(g["min"], e.min()),
              f"strain gauge {label}: bottom fibre's strain, final, max and min")
    packing = run.sensor("all_rocks")
    check(rep["packing_all_rocks"]["last"]["solid_fraction"] == packing["solid_fraction"][-1],
          "the rocks' solid fraction at the end")
    hold = rep["hold"]
    h0, h1 = hold["window"]
    check(h1 == t[-1] and close(h1 - h0, 0.1), "the hold: the run's last 0.1 s (scene's post step)")
    base = run.sensor("base")
    held = base["fz"][window_mask(base["time"], h0 - 1e-9, h1 + 1e-9)]
    check(close(hold["base_reaction_N"], -held.mean()), "base reaction in the hold")
    check(close(hold["base_reaction_sd_N"], held.std(), rel=1e-6),
          "its standard deviation (the report's from the mean square: round-off)")
    frozen = 0.0
    if "frozen_support_N" in hold:
        f = run.sensor("frozen")
        frozen = f["fz"][window_mask(f["time"], h0 - 1e-9, h1 + 1e-9)].mean()
        check(close(hold["frozen_support_N"], frozen), "force holding the frozen rocks")
    check(close(hold["balance_rel"], (-held.mean() + frozen - hold["expected_N"]) /
                hold["expected_N"], rel=1e-9), "force balance of the hold")
    # the cells' pressures (vertical force of the rocks over the cell's top) and the rocks'
    # weight (solid fraction x box x density x g), with the sizes from the run's scene
    dem = run.scene()["dem"]
    for w in (w for w in dem["walls"] if "body" in w and w["name"].startswith("cell")):
        lo, hi = w["box"]["lo"], w["box"]["hi"]
        cell = run.sensor(w["name"])
        fz = cell["fz"][window_mask(cell["time"], h0 - 1e-9, h1 + 1e-9)]
        pressure = -fz.mean() / ((hi[0] - lo[0]) * (hi[1] - lo[1])) / 1e3
        check(close(hold["cell_pressure_kPa"][w["name"]], pressure), f"{w['name']}: pressure")
    box = next(s for s in dem["sensors"] if s["name"] == "all_rocks")
    rho = next(m for m in dem["materials"] if m["name"] == "granite")["density"]
    phi = packing["solid_fraction"][window_mask(packing["time"], h0 - 1e-9, h1 + 1e-9)].mean()
    check(close(hold["rocks_weight_N"], phi * np.prod(np.subtract(box["hi"], box["lo"])) * rho
                * 9.81), "the rocks' weight in the hold")
    # the fields at the end: each rock's surface around its centre, the walls' forces as
    # their sensors read them
    rocks = run.particles(t[-1])
    shapes = rocks.shapes
    ids = shapes.point_data["id"]
    check(shapes.cell_type == "Triangle" and set(ids) == set(rocks["id"]),
          "every rock has its triangle surface")
    centre = {k: (x, r) for k, x, r in zip(rocks["id"], rocks.points, rocks["radius"])}
    check(all(np.linalg.norm(shapes.points[ids == k].mean(axis=0) - x) < r
              for k, (x, r) in centre.items()), "each surface lies around its rock's centre")
    walls = run.walls(t[-1])
    check(walls["box"].cell_data["force"][0].tolist() ==
          [base[c][-1] for c in ("fx", "fy", "fz")], "the box's force in the field = sensor_base")


def main(argv):
    mode = argv[0] if argv else ""
    with tempfile.TemporaryDirectory(prefix="post_api_") as d:
        if mode == "units":
            units_csv(Path(d))
            units_needs()
            units_fields(Path(d))
            units_help(Path(d))
            units_run(Path(d))
        elif mode in ("beam", "sheet", "sleeper", "tutorial") and len(argv) == 2:
            globals()[mode](os.path.abspath(argv[1]), d)
        else:
            print(__doc__, file=sys.stderr)
            return 2
    print(f"{len(FAILURES)} failure(s)" if FAILURES else "all passed")
    return 1 if FAILURES else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
