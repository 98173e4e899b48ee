"""ctest check of the C++ and Python SDKs as installed: `cmake --install` of the protocol
library and the Python package into a temporary prefix, then

  * examples/cpp_spring_bed (an out-of-tree C++ backend) configured and built against the
    installed CMake package only (find_package(demfemProtocol)), and used by a coupled run:
    the spheres of cases/beam_fixed_ci.toml settle on it (one-way static) and its springs
    carry exactly the settled weight (its own spring_bed.csv against coupling.csv);
  * the installed Python package imported from <prefix>/lib/python3/dist-packages.

Usage: test_cpp_sdk.py DEMFEM_RUN BUILD_DIR SOURCE_DIR CXX_COMPILER
"""

import csv
import os
import re
import subprocess
import sys
import tempfile

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)
    return ok


def sh(*cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, **kw)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}")
    return r


def last_row(path):
    with open(path) as f:
        return list(csv.DictReader(f))[-1]


def main():
    demfem_run, build, source, cxx = sys.argv[1:5]
    with tempfile.TemporaryDirectory() as d:
        prefix = os.path.join(d, "prefix")
        for part in ("protocol/ipc", "protocol/python"):
            sh("cmake", "--install", os.path.join(build, part), "--prefix", prefix)
        bed = os.path.join(d, "bed")
        sh("cmake", "-S", os.path.join(source, "examples/cpp_spring_bed"), "-B", bed,
           "-DCMAKE_BUILD_TYPE=Release", f"-DCMAKE_PREFIX_PATH={prefix}", f"-DCMAKE_CXX_COMPILER={cxx}")
        sh("cmake", "--build", bed)
        exe = os.path.join(bed, "spring_bed")
        check(os.access(exe, os.X_OK), "spring_bed was not built")
        # The installed package was used, not the build tree.
        cache = open(os.path.join(bed, "CMakeCache.txt")).read()
        found = re.search(r"demfemProtocol_DIR:PATH=(.*)", cache)
        check(found and found.group(1).startswith(prefix), f"demfemProtocol found at {found and found.group(1)}")

        # As a user runs it: no --output-dir, so run.output_dir (out/<name>) is relative to the
        # folder demfem_run starts in, not to the scene's, where the backend runs; it is told
        # the folder (absolute) all the same and writes its spring_bed.csv there.
        out = os.path.join(d, "out", "spring_bed_static_ci")
        cmd = (f'fem.command=["{exe}", "--size", "1.0", "0.1", "--cells", "40", "4", "--z", "0.1", '
               f'"--stiffness", "1e10", "--mass", "100"]')
        r = subprocess.run([demfem_run, os.path.join(source, "examples/cpp_spring_bed/static_ci.toml"),
                            "--quiet", "--set", cmd],
                           capture_output=True, text=True, timeout=300, cwd=d)
        check(os.path.isfile(os.path.join(out, "spring_bed.csv")),
              "the backend wrote no spring_bed.csv into the run's output folder")
        if check(r.returncode == 0, f"coupled run failed ({r.returncode}): {r.stderr[-2000:]}"):
            c, b = last_row(os.path.join(out, "coupling.csv")), last_row(os.path.join(out, "spring_bed.csv"))
            weight, spring = -float(c["force_sum_z"]), float(b["spring_force"])
            print(f"spring_bed: settled weight {weight!r} N, spring force {spring!r} N, "
                  f"max z {b['max_z']} m (coupler: {c['fem_max_displacement']})")
            check(abs(weight - 51.0 * 9.81) < 1e-6 * weight, f"settled weight {weight}")
            # k z = f at every node: the springs pull down by the settled weight (z < 0).
            check(abs(spring + weight) <= 1e-12 * weight, f"spring force {spring} != -weight {weight}")
            check(float(b["max_z"]) == float(c["fem_max_displacement"]), "max z differs")
        for seg in re.findall(r"segment /(demfem-[0-9a-f]+)", r.stdout):
            check(not os.path.exists("/dev/shm/" + seg), f"segment {seg} left in /dev/shm")

        site = os.path.join(prefix, "lib/python3/dist-packages")
        r = subprocess.run([sys.executable, "-c",
                            "import demfem, numpy as np; "
                            "m = demfem.InterfaceMesh(np.zeros((3, 3)), np.array([[0, 1, 2]])); "
                            "print(demfem.__file__, m.node_count, demfem.PROTOCOL_VERSION)"],
                           capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=site))
        print("installed Python package:", r.stdout.strip(), r.stderr[-500:])
        check(r.returncode == 0 and r.stdout.startswith(site), "the installed Python package does not import")
    for f in failures:
        print("FAILED:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
