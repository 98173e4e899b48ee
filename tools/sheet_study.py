#!/usr/bin/python3
"""Stability and convergence studies of the steel-sheet case (docs/verification.md): the
command of tools/studies/sheet.py (`python3 -m studies sheet ...`), kept under its old name.

usage: tools/sheet_study.py stability   [--base cases/sheet_ci.toml] [--work DIR] [--bin DIR]
                                        [--end-time T]
       tools/sheet_study.py convergence [--base ...] [--work DIR] [--bin DIR] [--end-time T]
                                        [--window A,B] [--members LIST]
"""

import sys

from studies.sheet import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
