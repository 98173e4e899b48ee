"""ctest check of the FEniCSx backend (examples/fenicsx_beam/fenicsx_backend.py, dolfinx 0.5
through the Python SDK): the beam case coupled through it (examples/fenicsx_beam/
beam_fixed_ci.toml: 51 kg of spheres settled on the clamped steel beam, one-way static) gives
the mid-span deflection of fem_server within 0.5 %.

The elements differ (FEniCSx: Q2 Lagrange hexahedra; fem_server: hex8 with incompatible
modes), so the reference is fem_server's mesh-converged value: Richardson extrapolation (with
the observed order) of the same scene run by fem_server on 20 x 2 x 2, 40 x 4 x 4 and
80 x 8 x 8 cells (--fem-backend fem, the same spheres). FEniCSx runs on 20 x 2 x 2 and
40 x 4 x 4 cells; the finer must be within 0.5 % of the reference and closer than the coarser.

Usage: test_fenicsx.py DEMFEM_RUN SOURCE_DIR. Exit 77 (skipped) when dolfinx is not importable.
"""

import csv
import math
import os
import re
import subprocess
import sys
import tempfile


def deflection(demfem_run, scene, out, *extra):
    r = subprocess.run([demfem_run, scene, "--output-dir", out, "--quiet", *extra],
                       capture_output=True, text=True, timeout=600)
    for seg in re.findall(r"segment /(demfem-[0-9a-f]+)", r.stdout):
        if os.path.exists("/dev/shm/" + seg):
            raise RuntimeError(f"segment {seg} left in /dev/shm")
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(extra)}: exit {r.returncode}: {r.stderr[-3000:]}")
    with open(os.path.join(out, "beam_check.csv")) as f:
        return -float(next(csv.DictReader(f))["coupled"])


def main():
    demfem_run, source = sys.argv[1], os.path.abspath(sys.argv[2])
    probe = subprocess.run([sys.executable, "-c", "import dolfinx"], capture_output=True, text=True)
    if probe.returncode != 0:
        print(f"dolfinx is not importable by {sys.executable} ({probe.stderr.strip()[-300:]}; "
              "Debian: python3-dolfinx, which ./demfem setup installs): skipped")
        return 77
    scene = os.path.join(source, "examples/fenicsx_beam/beam_fixed_ci.toml")
    with tempfile.TemporaryDirectory() as d:
        ref = [deflection(demfem_run, scene, os.path.join(d, f"fem{n}"), "--fem-backend", "fem",
                          "--set", f"fem.mesh.box.cells=[{n}, {n // 10}, {n // 10}]") for n in (20, 40, 80)]
        fx = [deflection(demfem_run, scene, os.path.join(d, f"fx{n}"),
                         "--set", f"fem.external.cells=[{n}, {n // 10}, {n // 10}]") for n in (20, 40)]
    order = math.log2((ref[0] - ref[1]) / (ref[1] - ref[2]))
    inf = ref[2] + (ref[2] - ref[1]) / (2 ** order - 1)
    print("mid-span deflection (top face centre line), coupled, m:")
    for n, w in zip((20, 40, 80), ref):
        print(f"  fem_server hex8 {n} x {n // 10} x {n // 10}: {w:.6e} ({100 * (w / inf - 1):+.3f} %)")
    print(f"  fem_server Richardson (observed order {order:.2f}): {inf:.6e}")
    for n, w in zip((20, 40), fx):
        print(f"  FEniCSx Q2 {n} x {n // 10} x {n // 10}: {w:.6e} ({100 * (w / inf - 1):+.3f} %)")
    failures = []
    if not abs(fx[1] / inf - 1) < 0.005:
        failures.append(f"FEniCSx 40 x 4 x 4 differs by {100 * (fx[1] / inf - 1):+.3f} % (tolerance 0.5 %)")
    if not abs(fx[1] - inf) < abs(fx[0] - inf):
        failures.append("FEniCSx does not converge towards fem_server's value")
    if not 1.0 < order < 2.5:
        failures.append(f"fem_server's observed order {order:.2f} is outside (1, 2.5)")
    for f in failures:
        print("FAILED:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
