"""ctest check of a modal analysis' output, opened with ParaView's own XDMF reader.

Runs cases/beam_modes.toml with demfem_run (fem.analysis = "modal"), then
tools/inspect_output.py under pvpython (ParaView 5.11, Debian python3-paraview), and checks
what ParaView shows of fem_modes.xdmf: one time step per mode (times 1 .. N), the beam's 189
nodes and 80 hexahedra, the point arrays mode_shape and mode_shape_unit (3 components), the
unit shape scaled to a largest nodal |u| of 1 and parallel to the mass-normalised one; and that
fem_modes.csv lists the same N modes with ascending frequencies, its y/z bending pairs equal.

Usage: check_modal_output.py DEMFEM_RUN SOURCE_DIR. Exit 77 (ctest: skipped) without pvpython.
"""

import csv
import json
import math
import os
import sys

from pv_checks import Checks, inspect_output, scene_run


def main():
    check = Checks()
    with scene_run("cases/beam_modes.toml", "--quiet") as c:
        with open(os.path.join(c.out, "fem_modes.csv")) as f:
            rows = list(csv.DictReader(f))
        seen = inspect_output(c.pvpython, c.source, c.out, 200)
        if seen is None:
            return 1

    n = 12
    freqs = [float(row["frequency"]) for row in rows]
    check(len(rows) == n, f"fem_modes.csv has {len(rows)} modes, expected {n}")
    check(all(a <= b for a, b in zip(freqs, freqs[1:])), f"frequencies not ascending: {freqs}")
    check(abs(freqs[0] / freqs[1] - 1) < 1e-9, f"first bending pair differs: {freqs[:2]}")
    check(all(float(row["residual"]) < 1e-8 for row in rows), "a mode's residual exceeds 1e-8")
    m = seen.get("fem_modes.xdmf")
    if m is None:
        print("fem_modes.xdmf not opened by ParaView")
        return 1
    check(m["reader"].startswith("Xdmf3Reader"), f"reader {m['reader']}")
    check(m["times"] == [float(k) for k in range(1, n + 1)], f"times {m['times']}")
    for step in m["steps"]:
        k = int(step["time"])
        check(step["points"] == 189 and step["cells"] == 80,
              f"mode {k}: {step['points']} points, {step['cells']} cells")
        check(step["cell_types"] == [12], f"mode {k}: cell types {step['cell_types']}")
        arrays = step["arrays"]
        for name in ("mode_shape", "mode_shape_unit"):
            a = arrays.get(name)
            check(a is not None and a["association"] == "point" and a["components"] == 3,
                  f"mode {k}: {name} missing or not a 3-component point array")
        if "mode_shape" not in arrays or "mode_shape_unit" not in arrays:
            continue
        shape, unit = arrays["mode_shape"]["values"], arrays["mode_shape_unit"]["values"]
        norms = [math.sqrt(sum(c * c for c in v)) for v in unit]
        check(abs(max(norms) - 1.0) < 1e-12, f"mode {k}: largest |mode_shape_unit| {max(norms)}")
        scale = max(math.sqrt(sum(c * c for c in v)) for v in shape)
        err = max(abs(a - b * scale) for s, u in zip(shape, unit) for a, b in zip(s, u))
        check(err < 1e-12 * scale, f"mode {k}: mode_shape_unit is not mode_shape scaled ({err})")
    print(json.dumps({"frequencies_hz": freqs, "times": m["times"]}))
    return check.report()


if __name__ == "__main__":
    sys.exit(main())
