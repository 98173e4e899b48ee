#!/usr/bin/python3
"""The thesis's parameter studies on the sleeper (ch. 6, figs. 6.7, 6.10, 6.12) and the DEM
time-step study on the small sleeper chain, with seeds: the command of
tools/studies/sleeper.py (`python3 -m studies sleeper ...`, where the docstring says what
each study runs), kept under its old name.

usage: tools/sleeper_study.py run STUDY [STUDY ...] [--seeds 1,2,3] [--cycles 3] [--jobs 2]
                              [--out out/sleeper_study] [--bin-dir build/bin]
       tools/sleeper_study.py collect STUDY [STUDY ...] [--out ...] [--figures docs/figures]

STUDY is time_scale, friction, triangles, dt or freeze.
"""

import sys

from studies.sleeper import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
