#!/usr/bin/env bash
# GPU checks of the DEM engine in one batch, for a session that is lent a GPU machine (which
# lacks the build dependencies; see ../shared/device/README.md).
#
#   tools/gpu_session.sh pack     (here, on the development machine) builds build-gpu with
#                                 CUDA for Hopper (sm_90) and packs test_dem_core, dem_throughput
#                                 and dem_server into .gpu (git ignores it)
#   tools/gpu_session.sh run      (on the GPU machine, repository root; pass carry [".gpu"])
#                                 runs the [gpu] tests (CPU vs CUDA trajectories) and the
#                                 throughput bench up to 10^6 spheres, the beds settled on the
#                                 GPU; writes log and JSON under $OUT (or ./gpu_out)
#
# One device call runs at most 10 minutes: `run` keeps within it by timing out each part.
set -euo pipefail
cd "$(dirname "$0")/.."

case "${1:-}" in
  pack)
    cmake -S . -B build-gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DDEMFEM_CUDA=ON \
      -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null
    cmake --build build-gpu -j2 --target test_dem_core dem_throughput dem_server
    exes=(build-gpu/tests/dem/test_dem_core build-gpu/bench/dem_throughput
          build-gpu/bin/dem_server)
    for e in "${exes[@]}"; do [ -x "$e" ] || { echo "gpu_session: missing $e" >&2; exit 1; }; done
    ../shared/device/bundle.sh .gpu "${exes[@]}"  # .gitignore holds /.gpu/
    ;;
  run)
    out=${OUT:-gpu_out}
    mkdir -p "$out"
    nvidia-smi > "$out/nvidia-smi.txt" 2>&1 || true
    # CPU-vs-CUDA comparisons; they must not skip here (a skip says why in the log)
    timeout 180 .gpu/run.sh test_dem_core "[gpu]" -s --durations yes \
      > "$out/gpu_tests.log" 2>&1 || echo "gpu tests: exit $?" >> "$out/gpu_tests.log"
    # throughput: settled beds cached under $out/cache; 10^6 spheres settle on the GPU
    timeout 360 .gpu/run.sh dem_throughput --max-particles 1000000 --threads 1 16 \
      --settle-threads 16 --cache "$out/cache" --json "$out/dem_throughput.json" \
      > "$out/dem_throughput.log" 2>&1 || echo "bench: exit $?" >> "$out/dem_throughput.log"
    rm -rf "$out/cache"  # the beds are large and not needed back
    tail -n 30 "$out/gpu_tests.log" "$out/dem_throughput.log"
    ;;
  *)
    echo "usage: tools/gpu_session.sh pack|run" >&2
    exit 2
    ;;
esac
