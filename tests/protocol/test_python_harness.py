"""ctest checks of the Python SDK's test harness (demfem.testing.BackendHarness) and of its
installation with pip: the examples' Python backends stepped in-process, without a coupled run.

  spring_plate  examples/python_spring_plate: a static step gives z = F_z / k (exactly, as the
                model says); undamped dynamic steps under a constant load keep the
                oscillator's energy 1/2 m v^2 + 1/2 k (z - F/k)^2 (the trapezoidal rule
                conserves it: to 1e-12 relative); the plate's nodes move by z; a checkpoint
                restored and stepped again gives the same bits as the first pass
  dem_spheres   examples/python_dem_spheres: one sphere settles on a flat 2-triangle plate; the
                forces on the nodes sum to its weight m g (to 1e-6 relative, damped) and
                split as the contact point's barycentric weights; dem_positions are the
                kinematics' x + v dt + a dt^2 / 2; checkpoint and restore give the same bits
  checks        what a coupled run refuses, the harness refuses with the same text: complex
                diagnostics, more than 8 of them, a FEM backend without a mesh, a DEM
                backend without one; `cancelled` follows harness.cancel(); the temporary
                checkpoint folder is gone after the `with` block
  pip_install   pip installs protocol/python offline (--no-index: the in-tree build backend
                needs no package) into a fresh virtual environment in a temporary folder;
                that environment's Python imports demfem from it (not from the build tree)
                and steps the spring plate with the harness; the source tree is left as it was

Usage: test_python_harness.py CASE SOURCE_DIR (the build tree's package on PYTHONPATH, except
for pip_install, which installs its own).
"""

import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap

import numpy as np

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
    return ok


def load_example(source_dir, relative):
    """An example backend's module, loaded from its file (examples are scripts, not packages)."""
    path = os.path.join(source_dir, relative)
    spec = importlib.util.spec_from_file_location(os.path.splitext(os.path.basename(path))[0], path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


PLATE = {"size": [1.0, 0.1], "cells": [4, 1], "z": 0.1, "mass": 10.0, "stiffness": 1e7,
         "damping": 0.0}


def case_spring_plate(source_dir):
    import demfem
    from demfem.testing import BackendHarness
    plate = load_example(source_dir, "examples/python_spring_plate/spring_plate.py")
    with BackendHarness(plate.SpringPlate(PLATE)) as h:
        n = h.mesh.node_count
        check(n == 10 and h.mesh.triangle_count == 8, f"plate mesh: {n} nodes")
        check(np.array_equal(h.positions, h.mesh.positions), "positions start at the reference")
        forces = np.zeros((n, 3))
        forces[:, 2] = -500.0 / n  # 500 N down, spread over the nodes
        values = h.step(1e-3, static=True, forces=forces)
        z = -500.0 / 1e7
        check(values[0] == abs(z), f"static |z| {values[0]!r}, expected {abs(z)!r}")
        check(np.array_equal(h.positions[:, 2], h.mesh.positions[:, 2] + z),
              "static: every node moved by z")
        check(len(values) == 8 and values[4:] == [0.0] * 4, f"diagnostics padded: {values}")

    # Dynamic, undamped, from rest at z = 0 under the same load: the trapezoidal rule keeps
    # 1/2 m v^2 + 1/2 k (z - F/k)^2 (F/k: the static equilibrium).
    with BackendHarness(plate.SpringPlate(PLATE)) as h:
        m, k, f_total = PLATE["mass"], PLATE["stiffness"], -500.0
        energy0 = 0.5 * k * (f_total / k) ** 2
        worst = 0.0
        for _ in range(40):
            values = h.step(1e-4, forces=forces)
            z = h.positions[0, 2] - h.mesh.positions[0, 2]
            v = h.velocities[0, 2]
            energy = 0.5 * m * v * v + 0.5 * k * (z - f_total / k) ** 2
            worst = max(worst, abs(energy - energy0) / energy0)
        check(worst < 1e-12, f"trapezoidal energy drift {worst:.3e}, expected < 1e-12")
        check(np.all(h.velocities[:, 2] == h.velocities[0, 2]), "one velocity for every node")

        # Checkpoint, ten steps, restore, the same ten steps: the same bits.
        saved = h.checkpoint()
        check(saved.step == 40 and os.path.isfile(saved.path), f"checkpoint {saved}")
        first = [h.step(1e-4, forces=forces) for _ in range(10)]
        after_first = h.positions.copy()
        h.restore(saved)
        check(h.step_index == 40, f"restore: step index {h.step_index}")
        second = [h.step(1e-4, forces=forces) for _ in range(10)]
        check(first == second, "restored run: other diagnostics")
        check(np.array_equal(after_first, h.positions), "restored run: other positions")
        folder = h.checkpoint_dir
    check(not os.path.exists(folder), "the harness's checkpoint folder outlived the with block")
    return demfem


def flat_plate(side=0.2):
    import demfem
    nodes = np.array([[0, 0, 0], [side, 0, 0], [side, side, 0], [0, side, 0]], dtype=float)
    return demfem.InterfaceMesh(nodes, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32))


def case_dem_spheres(source_dir):
    import demfem
    from demfem.testing import BackendHarness
    spheres = load_example(source_dir, "examples/python_dem_spheres/spheres.py")
    params = {"centres": [[0.05, 0.12, 0.0095]], "radius": 0.01, "mass": 0.1,
              "stiffness": 1e5, "damping_ratio": 0.7, "gravity": [0.0, 0.0, -9.81]}
    mesh = flat_plate()
    with BackendHarness(spheres.Spheres(params), role=demfem.Role.dem, mesh=mesh) as h:
        for _ in range(200):  # 0.2 s: settled (the contact's period is 6 ms, damped at 0.7)
            h.step(1e-3, substeps=20)
        total = h.forces.sum(axis=0)
        weight = 0.1 * 9.81
        check(abs(-total[2] - weight) < 1e-6 * weight,
              f"settled: the nodes carry {-total[2]!r} N, the weight is {weight!r} N")
        check(np.all(np.abs(total[:2]) < 1e-12), f"no tangential force: {total}")
        # The contact point (0.05, 0.12) lies in triangle (0, 2, 3) = (0, 0), (0.2, 0.2),
        # (0, 0.2): barycentric weights 0.4 (node 0), 0.25 (node 2), 0.35 (node 3); node 1
        # carries nothing.
        share = -h.forces[:, 2] / weight
        check(np.allclose(share, [0.4, 0.0, 0.25, 0.35], atol=1e-6), f"node shares {share}")

        # The structure moves up at 0.01 m/s, accelerating at 2 m/s^2: dem_positions are
        # where its nodes are at the step's end.
        x, v, a = mesh.positions, np.tile([0.0, 0.0, 0.01], (4, 1)), np.tile([0.0, 0.0, 2.0], (4, 1))
        dt = 1e-3
        h.step(dt, substeps=10, kinematics=(x, v, a))
        check(np.allclose(h.dem_positions, x + v * dt + 0.5 * a * dt * dt, rtol=0, atol=1e-15),
              "dem_positions: x + v dt + a dt^2 / 2")

        saved = h.checkpoint()
        first = [h.step(dt, substeps=10) for _ in range(5)]
        forces_first = h.forces.copy()
        h.restore(saved)
        second = [h.step(dt, substeps=10) for _ in range(5)]
        check(first == second and np.array_equal(forces_first, h.forces),
              "restored DEM: other diagnostics or forces")


def case_checks(source_dir):
    import demfem
    from demfem.testing import BackendHarness
    plate = load_example(source_dir, "examples/python_spring_plate/spring_plate.py")

    class Returns(plate.SpringPlate):
        def __init__(self, values):
            super().__init__(PLATE)
            self.values = values

        def step(self, cmd, buffers):
            super().step(cmd, buffers)
            return self.values

    def refused(values, expected):
        with BackendHarness(Returns(values)) as h:
            try:
                h.step(1e-3)
            except (RuntimeError, ValueError) as e:  # as the C++ exceptions map
                return check(expected in str(e), f"refusal of {values!r}: {e}")
        return check(False, f"step() returning {values!r} was accepted")

    refused([1.0 + 2.0j], "complex numbers")
    refused([0.0] * 9, "at most 8 are reported")
    refused("text", "wrong type")

    class NoMesh(plate.SpringPlate):
        def published_mesh(self):
            return None

    try:
        BackendHarness(NoMesh(PLATE))
        check(False, "a FEM backend without a mesh was accepted")
    except ValueError as e:
        check("must publish its interface mesh" in str(e), f"no mesh: {e}")
    spheres = load_example(source_dir, "examples/python_dem_spheres/spheres.py")
    try:
        BackendHarness(spheres.Spheres({"centres": [[0, 0, 1]], "radius": 0.01, "mass": 1.0,
                                        "stiffness": 1e5}), role=demfem.Role.dem)
        check(False, "a DEM backend without the structure's mesh was accepted")
    except ValueError as e:
        check("needs the structure's InterfaceMesh" in str(e), f"DEM without mesh: {e}")

    class Polls(plate.SpringPlate):
        def step(self, cmd, buffers):
            return [1.0 if self.cancelled else 0.0]

    with BackendHarness(Polls(PLATE)) as h:
        check(h.step(1e-3)[0] == 0.0, "cancelled before cancel()")
        h.cancel()
        check(h.step(1e-3)[0] == 1.0, "not cancelled after cancel()")


def case_pip_install(source_dir):
    package = os.path.join(source_dir, "protocol", "python")
    before = {p for p in os.listdir(package)}
    with tempfile.TemporaryDirectory(prefix="demfem-pip-") as tmp:
        venv = os.path.join(tmp, "venv")
        subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", venv], check=True)
        python = os.path.join(venv, "bin", "python")
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        # The compiler cache the developers' builds use, when there is one (faster; same result).
        if shutil.which("ccache") and "CCACHE_DIR" in env:
            env["CXX"] = "ccache g++"
        r = subprocess.run([python, "-m", "pip", "install", "--no-index",
                            "--no-cache-dir", "--quiet", package],
                           env=env, capture_output=True, text=True, timeout=900)
        if not check(r.returncode == 0, f"pip install failed ({r.returncode}):\n{r.stdout}\n{r.stderr}"):
            return
        script = textwrap.dedent(f"""
            import os, sys
            import numpy as np
            import demfem
            from demfem.testing import BackendHarness
            where = os.path.realpath(demfem.__file__)
            assert where.startswith(os.path.realpath({venv!r})), "demfem imported from " + where
            sys.path.insert(0, {os.path.join(source_dir, "examples", "python_spring_plate")!r})
            import spring_plate
            with BackendHarness(spring_plate.SpringPlate({PLATE!r})) as h:
                f = np.zeros((h.mesh.node_count, 3)); f[:, 2] = -50.0
                values = h.step(1e-3, static=True, forces=f)
            assert values[0] == 500.0 / 1e7, values
            print("installed", demfem.PROTOCOL_VERSION, where)
        """)
        r = subprocess.run([python, "-c", script], env=env, cwd=tmp, capture_output=True,
                           text=True, timeout=120)
        check(r.returncode == 0 and "installed" in r.stdout,
              f"the installed SDK ({r.returncode}):\n{r.stdout}\n{r.stderr}")
        print(r.stdout.strip())
        leftovers = sorted(set(os.listdir(package)) - before - {"__pycache__"})
        check(not leftovers, f"pip install left {leftovers} in protocol/python")


def main():
    case, source_dir = sys.argv[1], sys.argv[2]
    cases = {"spring_plate": case_spring_plate, "dem_spheres": case_dem_spheres,
             "checks": case_checks, "pip_install": case_pip_install}
    if case not in cases:
        print(f"unknown case {case!r}; one of {sorted(cases)}", file=sys.stderr)
        return 2
    cases[case](source_dir)
    for f in failures:
        print("FAILED:", f, file=sys.stderr)
    print(f"{case}: {'FAILED' if failures else 'passed'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
