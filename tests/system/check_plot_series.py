"""ctest check of tools/plot_series.py: a small CSV becomes a PNG; a bad column is refused.
Exit 77 (ctest: skipped) when matplotlib is not installed."""

import os
import subprocess
import sys
import tempfile

from module_or_skip import module_or_skip

module_or_skip("matplotlib", "python3-matplotlib")

script = sys.argv[1]
with tempfile.TemporaryDirectory() as d:
    csv = os.path.join(d, "coupling.csv")
    with open(csv, "w") as f:
        f.write("step,time,drift,energy_error\n")
        for i in range(20):
            f.write(f"{i},{(i + 1) * 1e-4},{1e-8 / (i + 1)},{(-1) ** i * 1e-6}\n")
    r = subprocess.run([sys.executable, script, csv], capture_output=True, text=True)
    png = os.path.join(d, "coupling.png")
    if r.returncode != 0 or not os.path.isfile(png):
        print("plot failed:", r.returncode, r.stdout, r.stderr)
        sys.exit(1)
    with open(png, "rb") as f:
        if f.read(8) != b"\x89PNG\r\n\x1a\n":
            print("not a PNG:", png)
            sys.exit(1)
    r = subprocess.run([sys.executable, script, csv, "--columns", "nonexistent"],
                       capture_output=True, text=True)
    if r.returncode != 2 or "nonexistent" not in r.stderr:
        print("a bad column was not refused:", r.returncode, r.stderr)
        sys.exit(1)
print("ok")
