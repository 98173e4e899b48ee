"""`python3 -m studies STUDY ...`: the studies of this package, each with its own options."""

import sys

from studies import sheet, sleeper

STUDIES = {"sheet": sheet.main, "sleeper": sleeper.main}


def main(argv):
    if not argv or argv[0] not in STUDIES:
        print("usage: python3 -m studies {" + ",".join(STUDIES) + "} ...  (docs/cases.md; "
              "`python3 -m studies sheet --help`)", file=sys.stderr)
        return 2
    return STUDIES[argv[0]](argv[1:])
