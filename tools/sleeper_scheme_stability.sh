#!/usr/bin/env bash
# Stability of each coupling scheme on a sleeper case (issue 13): runs the scene's load case
# (its prepared bed is reused) with every scheme at the given dt_F, and prints per run the exit
# status (0 ran through, 3 blow-up) and the mean settlement of the bottom probes in a window.
#
#   tools/sleeper_scheme_stability.sh SCENE OUT "1e-4 1e-3" [T0 T1] > table.txt
#
# SCENE: cases/sleeper_mini.toml or cases/sleeper_ci.toml (its beds made first, e.g. by
# `demfem run SCENE` once); OUT: a folder for the runs; T0 T1: the settlement window (s,
# default 0.25 0.35: the static hold of sleeper_mini). Uses build/bin/demfem_run.
set -uo pipefail
scene=$1 out=$2 dts=$3 t0=${4:-0.25} t1=${5:-0.35}
run=${DEMFEM_RUN:-build/bin/demfem_run}
mkdir -p "$out"
printf '%-26s %-8s %-5s %-14s %s\n' scheme dt_F exit settlement_m wall_s
for dt in $dts; do
  for variant in just_in_time just_in_time+avg predictive predictive+avg concurrent implicit-iqn implicit-aitken; do
    name=${variant%%+*} avg=false acc=
    [[ $variant == *+avg ]] && avg=true
    case $variant in
      implicit-iqn) name=implicit acc=iqn-ils ;;
      implicit-aitken) name=implicit acc=aitken ;;
    esac
    sets=(--set "coupling.scheme=\"$name\"" --set "coupling.force_averaging=$avg" --set "fem.dt=$dt")
    [[ -n $acc ]] && sets+=(--set "coupling.acceleration=\"$acc\"")
    dir=$out/${variant}_$dt
    start=$(date +%s.%N)
    "$run" --quiet --no-post "$scene" --output-dir "$dir" "${sets[@]}" > "$dir.log" 2>&1
    rc=$?
    wall=$(echo "$(date +%s.%N) - $start" | bc)
    s=$(/usr/bin/python3 - "$dir/fem_monitor.csv" "$t0" "$t1" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
t0, t1 = float(sys.argv[2]), float(sys.argv[3])
cols = [c for c in rows[0] if c.startswith("b") and c.endswith("_uz")]
w = [sum(float(r[c]) for c in cols) / len(cols) for r in rows if t0 <= float(r["time"]) <= t1]
print(f"{sum(w) / len(w):.6g}" if w else f"none(t_end={rows[-1]['time']})")
PY
)
    printf '%-26s %-8s %-5s %-14s %.0f\n' "$variant" "$dt" "$rc" "$s" "$wall"
  done
done
