#!/usr/bin/env bash
# GPU checks of the DEM engine in one batch, for a session that is lent a GPU machine (which
# lacks the build dependencies; see ../shared/device/README.md). Issue 39's figures.
#
#   tools/gpu_session.sh pack   (here, on the development machine) builds build-gpu with CUDA
#                               for Hopper (sm_90) and packs test_dem_core, dem_throughput,
#                               poly_throughput, dem_server, fem_server and demfem_run into .gpu
#                               (git ignores it), with the settled 10^4-rock bed of
#                               poly_throughput (settled here once, cached in build-gpu)
#   tools/gpu_session.sh run    (on the GPU machine, repository root; pass carry [".gpu"])
#                               builds nothing; runs, each step under its own timeout and all
#                               within 8 minutes (the device call's limit is 10):
#                                 1. every [gpu] test (CPU vs CUDA: spheres, static and moving
#                                    walls, flexible mesh in both force modes, polyhedra under
#                                    both laws, the device-built neighbour list, periodic beds
#                                    of spheres and of rocks, frozen particles)
#                                 2. spheres 10^4, 10^5, 10^6 on the device (share of time in
#                                    detection), beds settled on the device
#                                 3. rocks of 30 triangles, 10^4 and 10^5 (10^5 tiled from the
#                                    packed 10^4 bed)
#                                 4. 1, 2, 4, 8 concurrent DEM processes on the device (10^5
#                                    spheres each; the aggregate rate)
#                                 5. CPU thread scaling 1, 2, 4, 8, 16 of spheres (10^5) and
#                                    rocks (10^4)
#                                 6. the sheet CI and sleeper CI cases through the three
#                                    processes with dem.backend = "cuda" (their beds are
#                                    prepared first by the CPU DEM, as the cases ask; the
#                                    sleeper's pressure cells are force-limited walls, which
#                                    the CUDA backend refuses so far: exit 2, key named)
#                                 7. the periodic block (150 rocks, periodic in x and y) for
#                                    0.1 s through dem_server, on the device and on 16 CPU
#                                    threads (wall times; the end states come back in $OUT)
#                                 8. spheres 10^7 and rocks 10^6, with what time is left
#                               JSON and logs under $OUT (or ./gpu_out); steps.json lists every
#                               step with its exit status, seconds, and why it was skipped.
#   tools/gpu_session.sh dry    (here, no GPU) the same script from a normal build (./build):
#                               the GPU steps are skipped and say so, the CPU steps run with
#                               small sizes and 1-2 threads, to prove the CPU half.
set -uo pipefail
cd "$(dirname "$0")/.."

# the polyhedron bed of the issue's target (docs/polyhedra.md, "Throughput"); pack and run
# must agree on it (the settling parameters name the cached bed)
poly_bed=(--triangles 30 --settle-time 0.3 --settle-max 1 --settle-ke 0.05 --settle-dt 6e-5)

pack() {
  set -e
  cmake -S . -B build-gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DDEMFEM_CUDA=ON \
    -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null
  cmake --build build-gpu -j2 --target test_dem_core dem_throughput poly_throughput dem_server \
    fem_server demfem_run
  exes=(build-gpu/tests/dem/test_dem_core build-gpu/bench/dem_throughput
        build-gpu/bench/poly_throughput build-gpu/bin/dem_server build-gpu/bin/fem_server
        build-gpu/bin/demfem_run)
  for e in "${exes[@]}"; do [ -x "$e" ] || { echo "gpu_session: missing $e" >&2; exit 1; }; done
  # the polyhedron bed: settled on this CPU (cached beside the executable), measured nowhere
  build-gpu/bench/poly_throughput --counts 10000 "${poly_bed[@]}" --threads 2 --no-gpu \
    --no-spheres --work 1 >/dev/null
  ../shared/device/bundle.sh .gpu "${exes[@]}"  # .gitignore holds /.gpu/
  mkdir -p .gpu/poly_cache
  cp build-gpu/bench/poly_throughput_cache/poly_bed_10000_* .gpu/poly_cache/
  du -sh .gpu
}

# ---- run / dry -------------------------------------------------------------------------
mode=${1:-}
case "$mode" in
  pack) pack; exit 0 ;;
  run | dry) ;;
  *) echo "usage: tools/gpu_session.sh pack|run|dry" >&2; exit 2 ;;
esac

out=${OUT:-gpu_out}
mkdir -p "$out"
out=$(cd "$out" && pwd)
start=$(date +%s)
budget=${GPU_SESSION_BUDGET:-470}  # s: all steps together (the call's limit is 600)
gpu=0
if [ "$mode" = run ] && nvidia-smi -L >"$out/nvidia-smi.txt" 2>&1; then gpu=1; fi
nvidia-smi >>"$out/nvidia-smi.txt" 2>&1 || true
if [ "$mode" = run ] && [ "$gpu" = 0 ]; then
  echo "gpu_session: run: no GPU here (nvidia-smi failed); the GPU steps will be skipped" >&2
fi

# the executables: the pack on the device, ./build for a dry run
exe() {
  if [ "$mode" = run ]; then
    echo ".gpu/run.sh $1"
  else
    case "$1" in
      test_dem_core) echo "build/tests/dem/test_dem_core" ;;
      dem_throughput | poly_throughput) echo "build/bench/$1" ;;
      *) echo "build/bin/$1" ;;
    esac
  fi
}

steps_json="$out/steps.json"
echo "[" >"$steps_json"
first=1
record() {  # name rc seconds note
  [ $first = 1 ] || echo "," >>"$steps_json"
  first=0
  printf '  {"step": "%s", "rc": %s, "seconds": %s, "note": "%s"}' "$1" "$2" "$3" "$4" \
    >>"$steps_json"
}
# step NAME NEEDS_GPU TIMEOUT COMMAND...: runs COMMAND (a shell string) under the smaller of
# TIMEOUT and the time left, its output in NAME.log; a GPU step without a GPU is skipped
step() {
  local name=$1 needs=$2 limit=$3
  shift 3
  local left=$((budget - ($(date +%s) - start)))
  if [ "$needs" = gpu ] && [ "$gpu" = 0 ]; then
    echo "gpu_session: $name: skipped (no GPU: $mode)" | tee "$out/$name.log"
    record "$name" null 0 "skipped: no GPU"
    return
  fi
  if [ "$left" -lt 15 ]; then
    echo "gpu_session: $name: skipped (${left} s left of ${budget})" | tee "$out/$name.log"
    record "$name" null 0 "skipped: out of time"
    return
  fi
  [ "$limit" -gt "$left" ] && limit=$left
  echo "gpu_session: $name (at most ${limit} s)"
  local t0 rc
  t0=$(date +%s)
  timeout --kill-after=5 "$limit" bash -c "$*" >"$out/$name.log" 2>&1
  rc=$?
  local note=""
  [ $rc = 124 ] || [ $rc = 137 ] && note="timed out after ${limit} s"
  record "$name" "$rc" "$(($(date +%s) - t0))" "$note"
  echo "gpu_session: $name: exit $rc ${note}"
}

if [ "$mode" = run ]; then
  sizes_gpu="--max-particles 1000000"
  threads="1 2 4 8 16"
  cpu_spheres="--only 100000"
  cpu_rocks="--counts 10000"
  poly_cache="--cache .gpu/poly_cache"
else  # small and short here: the commands, not the figures
  sizes_gpu="--max-particles 10000"
  threads="1 2"
  cpu_spheres="--only 1000 --work 2e5"
  cpu_rocks="--counts 300 --work 1e5"
  poly_cache=""
fi
cache="$out/cache"  # settled sphere beds (removed at the end: large)

# 1. the [gpu] tests: on the device they compare the CUDA backend with the CPU; here they run
#    their CPU half and say that they skipped the comparison
step gpu_tests any 120 "$(exe test_dem_core) '[gpu]' -s --durations yes -r compact"
# 2. spheres on the device, 10^4 to 10^6, settled there
step spheres_gpu gpu 150 "$(exe dem_throughput) $sizes_gpu --no-cpu --settle-backend cuda \
  --settle-threads 16 --cache $cache --json $out/spheres_gpu.json"
# 3. rocks of 30 triangles on the device: 10^4 (packed bed) and 10^5 (tiled from it)
step rocks_gpu gpu 90 "$(exe poly_throughput) --counts 10000 100000 ${poly_bed[*]} \
  --threads 16 --settle-threads 16 --no-spheres $poly_cache --json $out/rocks_gpu.json"
# 4. concurrent DEM processes sharing the device, 10^5 spheres each (the bed cached by 2.)
concurrent() {
  local k
  for k in 1 2 4 8; do
    local pids=()
    for ((p = 0; p < k; ++p)); do
      $(exe dem_throughput) --only 100000 --no-cpu --cache "$cache" \
        --json "$out/concurrent_${k}_${p}.json" >"$out/concurrent_${k}_${p}.log" 2>&1 &
      pids+=($!)
    done
    for p in "${pids[@]}"; do wait "$p"; done
  done
}
export -f concurrent exe
export mode out cache
step concurrent gpu 60 concurrent
# 5. CPU thread scaling on this machine's cores
step cpu_spheres any 60 "$(exe dem_throughput) $cpu_spheres --threads $threads --no-gpu \
  --cache $cache --json $out/cpu_spheres.json"
step cpu_rocks any 60 "$(exe poly_throughput) $cpu_rocks ${poly_bed[*]} --threads $threads \
  --no-gpu --no-spheres $poly_cache --json $out/cpu_rocks.json"
# 6. the CI cases end to end, the DEM on the device (here: the clear refusal, exit 2)
for scene in sheet_ci sleeper_ci; do
  mkdir -p "$out/$scene"
  if [ "$gpu" = 1 ]; then
    step "$scene" gpu 150 "cd $out/$scene && $(exe demfem_run | sed "s|^\.gpu|$PWD/.gpu|") \
      $PWD/cases/$scene.toml --set 'dem.backend=\"cuda\"' --quiet --no-post"
  else  # the command line and, after the CPU prepares the case's beds, the clear refusal of
        # a build without CUDA (exit 2)
    step "$scene" any 180 "cd $out/$scene && $PWD/$(exe demfem_run) $PWD/cases/$scene.toml \
      --set 'dem.backend=\"cuda\"' --quiet --no-post; rc=\$?; echo exit \$rc; [ \$rc = 2 ]"
  fi
done
# 7. a periodic scene on the device and on the CPU: the pour of cases/periodic_block.toml for
#    0.1 s (10^4 steps), output at the start and the end; the wall time of each (the end
#    states come back under $OUT/periodic_{cuda,cpu} to be compared on the development machine)
periodic_pair() {
  local b t0
  for b in cuda cpu; do
    mkdir -p "$out/periodic_$b"
    t0=$(date +%s%N)
    $(exe dem_server) --scene cases/periodic_block.toml --output-dir "$out/periodic_$b" --quiet \
      --set "dem.backend=\"$b\"" --set dem.threads=16 --set run.end_time=0.1 \
      --set run.output_interval=0.1 || return $?
    echo "periodic_$b: wall $((($(date +%s%N) - t0) / 1000000)) ms"
  done
}
export -f periodic_pair
if [ "$mode" = run ]; then
  step periodic gpu 90 periodic_pair
else
  step periodic any 30 "echo 'periodic: on the device only (two dem_server runs)'"
fi
# 8. the largest beds with the time left
step spheres_1e7_gpu gpu 200 "$(exe dem_throughput) --only 10000000 --max-particles 10000000 \
  --no-cpu --settle-backend cuda --settle-threads 16 --cache $cache \
  --json $out/spheres_1e7_gpu.json"
step rocks_1e6_gpu gpu 200 "$(exe poly_throughput) --counts 1000000 ${poly_bed[*]} --threads 16 \
  --settle-threads 16 --no-spheres $poly_cache --json $out/rocks_1e6_gpu.json"

echo "]" >>"$steps_json"
rm -rf "$cache"
echo "gpu_session: $mode done in $(($(date +%s) - start)) s; steps:"
cat "$steps_json"
