#!/usr/bin/python3
"""ctest: the manual's check for dated text in user pages (docs/_site/hooks.py, dated_text;
the strict site build turns each finding into an error). It finds what it must (a commit hash,
a load average, a date), leaves alone what only looks like one (a deflection, a segment's
name, a state hash, "load 51 kg"), honours an allowance (a whole page, or named sections; none
is allowed today), and finds nothing in the pages as they are.

  check_dated_text.py SOURCE_DIR
"""
import glob
import importlib.util
import os
import sys


def main(source):
    spec = importlib.util.spec_from_file_location("hooks", os.path.join(source, "docs", "_site", "hooks.py"))
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    failures = []
    must_find = {
        "measured at commit 7046fa2; with it": "a commit hash",
        "(commit 664a7193e2f5c1d0b9a8e7f6d5c4b3a2f1e0d9c8)": "a commit hash",
        "while five builds ran (load average ≈ 11), 20000": "a load average",
        "2 vCPU shared with other builds, load 10–13):": "a load average",
        "at commit x (load about 6) measured": "a load average",
        "Until 2026-12-05 the output folder": "a date",
    }
    for text, what in must_find.items():
        found = hooks.dated_text(text, "backends.md")
        if [w for _, w, _ in found] != [what]:
            failures.append(f"{text!r}: found {found}, expected {what}")
    must_pass = [
        "  coupled (DEM load)             -7.889088959e-07   -0.000e+00 % vs pure FEM",
        "beam check: load 51 kg (m g = 500.31 N; the interface forces sum to 500.31 N);",
        "demfem run: segment /demfem-73330389dd61a542",
        "prints 9d55523fcd4f93a3 (spheres), 06c537cda1f1f885",
        "a 2187 × 2188 matrix, 38 MB read per step; 1e-12 J; 0.0664972 of it",
    ]
    for text in must_pass:
        found = hooks.dated_text(text, "backends.md")
        if found:
            failures.append(f"{text!r}: flagged {found}")
    # No page is allowed dated text today: reliability.md and the sleeper section are checked
    # like every user page. The allowance itself (a whole page, or named sections) is checked
    # with an allowance set up here.
    if not hooks.dated_text("commit 7046fa2 (load average 12)", "reliability.md"):
        failures.append("reliability.md: a commit and a load average not flagged")
    sleeper = "## Timber sleeper on ballast (thesis ch. 6)\ncommit 7046fa2\n## Next\ncommit 7046fa2\n"
    if [n for n, _, _ in hooks.dated_text(sleeper, "cases.md")] != [2, 4]:
        failures.append("cases.md: the sleeper section not checked")
    saved = dict(hooks.DATED_TEXT_ALLOWED)
    hooks.DATED_TEXT_ALLOWED.update({"whole.md": None, "cases.md": {
        "sections": ["## Timber sleeper on ballast (thesis ch. 6)"]}})
    if hooks.dated_text("commit 7046fa2 (load average 12)", "whole.md"):
        failures.append("a page allowed whole is flagged")
    if [n for n, _, _ in hooks.dated_text(sleeper, "cases.md")] != [4]:
        failures.append("cases.md: an allowed section is flagged, or the next is not")
    hooks.DATED_TEXT_ALLOWED.clear()
    hooks.DATED_TEXT_ALLOWED.update(saved)
    if not hooks.dated_text("commit 7046fa2", "reports/x.md") == []:
        failures.append("reports/ is where the history belongs, yet flagged")
    docs = os.path.join(source, "docs")
    for path in sorted(glob.glob(os.path.join(docs, "**", "*.md"), recursive=True)):
        rel = os.path.relpath(path, docs)
        with open(path, encoding="utf-8") as f:
            for number, what, text in hooks.dated_text(f.read(), rel):
                failures.append(f"docs/{rel}:{number}: {what} ({text!r})")
    for f in failures:
        print("FAILED:", f)
    print("dated text check:", "FAILED" if failures else "passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
