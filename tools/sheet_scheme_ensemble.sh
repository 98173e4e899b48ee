#!/bin/bash
# An ensemble of sheet CI runs of one coupling scheme (docs/coupling.md, "Problem (c)").
#
# usage: tools/sheet_scheme_ensemble.sh OUT_DIR SCHEME FORCE_AVERAGING DT_F N [--set KEY=VALUE ...]
#   SCHEME just_in_time, predictive, concurrent or implicit (then IQN-ILS with the tolerances of
#   bench/coupling_schemes's sheet part); FORCE_AVERAGING true or false; DT_F the coupling step.
#
# The granular flow onto the sheet is chaotic: a change of the sheet's density by 1e-9 moves
# the mean deflection over the flow by up to 1 %. Run k of the ensemble (k = 0 .. N-1, N <= 10)
# is cases/sheet_ci.toml cut to 0.6 s, its steel density 7850 kg/m^3 + k * 1e-5 (a relative
# change of 1.3e-9 k, far below any physical meaning, so the runs are samples of the same flow).
# Run k goes to OUT_DIR/k; compare ensembles with
#   /usr/bin/python3 tools/sheet_scheme_errors.py --ensemble REF_DIR/* -- OUT_DIR/*
# Needs the build in build/ (build/bin/demfem_run and the solvers).
set -euo pipefail
if [ $# -lt 5 ]; then
  sed -n '2,15p' "$0" >&2
  exit 2
fi
out=$1 scheme=$2 avg=$3 dt=$4 n=$5
shift 5
if ! [[ "$n" =~ ^[0-9]+$ ]] || [ "$n" -lt 1 ] || [ "$n" -gt 10 ]; then
  echo "sheet_scheme_ensemble.sh: N = $n, accepted 1 .. 10" >&2
  exit 2
fi
root=$(cd "$(dirname "$0")/.." && pwd)
sets=(--set run.end_time=0.6 --set "coupling.scheme=\"$scheme\"" --set "coupling.force_averaging=$avg"
  --set coupling.diagnostics_interval=1 --set "fem.dt=$dt" --set run.output_interval=0)
if [ "$scheme" = implicit ]; then
  sets+=(--set 'coupling.acceleration="iqn-ils"' --set coupling.displacement_tolerance=1e-3
    --set coupling.force_tolerance=1e-2 --set coupling.force_abs_tolerance=1e-6
    --set coupling.displacement_abs_tolerance=1e-12 --set coupling.max_iterations=50)
fi
mkdir -p "$out"
for ((k = 0; k < n; ++k)); do
  status=0
  "$root/build/bin/demfem_run" --bin-dir "$root/build/bin" "$root/cases/sheet_ci.toml" \
    --output-dir "$out/$k" --quiet --no-post "${sets[@]}" \
    --set "fem.materials[0].density=7850.0000$k" "$@" >"$out/$k.log" 2>&1 || status=$?
  echo "run $k: exit $status ($out/$k.log)"
done
