#!/usr/bin/env bash
# GPU checks of the DEM engine in one batch, for a session that is lent a GPU machine (which
# lacks the build dependencies; see ../shared/device/README.md).
#
#   tools/gpu_session.sh pack     (here, on the development machine) builds build-gpu with
#                                 CUDA for Hopper (sm_90) and packs test_dem_core, dem_throughput,
#                                 poly_throughput and dem_server into .gpu (git ignores it), with
#                                 the settled 10^4-rock and sphere beds of poly_throughput (settled
#                                 here once, cached in build-gpu, so the device does not settle)
#   tools/gpu_session.sh run      (on the GPU machine, repository root; pass carry [".gpu"])
#                                 runs the [gpu] tests (CPU vs CUDA trajectories, spheres and
#                                 polyhedra under both contact laws), the polyhedron GPU row
#                                 (10^4 rocks of 30 triangles, both laws) and the throughput
#                                 bench up to 10^6 spheres, the beds settled on the GPU; writes
#                                 log and JSON under $OUT (or ./gpu_out)
#
# One device call runs at most 10 minutes: `run` keeps within it by timing out each part.
set -euo pipefail
cd "$(dirname "$0")/.."

# the polyhedron bed of the issue's target (docs/polyhedra.md, "Throughput"); pack and run
# must agree on it (the settling parameters name the cached bed)
poly_bed=(--counts 10000 --triangles 30 --settle-time 0.3 --settle-max 1 --settle-ke 0.05
          --settle-dt 6e-5)

case "${1:-}" in
  pack)
    cmake -S . -B build-gpu -G Ninja -DCMAKE_BUILD_TYPE=Release -DDEMFEM_CUDA=ON \
      -DCMAKE_CUDA_ARCHITECTURES=90 >/dev/null
    cmake --build build-gpu -j2 --target test_dem_core dem_throughput poly_throughput dem_server
    exes=(build-gpu/tests/dem/test_dem_core build-gpu/bench/dem_throughput
          build-gpu/bench/poly_throughput build-gpu/bin/dem_server)
    for e in "${exes[@]}"; do [ -x "$e" ] || { echo "gpu_session: missing $e" >&2; exit 1; }; done
    # the polyhedron beds: settled on this CPU (cached beside the executable), measured nowhere
    build-gpu/bench/poly_throughput "${poly_bed[@]}" --threads 2 --no-gpu --work 1 >/dev/null
    ../shared/device/bundle.sh .gpu "${exes[@]}"  # .gitignore holds /.gpu/
    mkdir -p .gpu/poly_cache
    cp build-gpu/bench/poly_throughput_cache/poly_bed_10000_* .gpu/poly_cache/
    du -sh .gpu
    ;;
  run)
    out=${OUT:-gpu_out}
    mkdir -p "$out"
    nvidia-smi > "$out/nvidia-smi.txt" 2>&1 || true
    # CPU-vs-CUDA comparisons; they must not skip here (a skip says why in the log)
    timeout 150 .gpu/run.sh test_dem_core "[gpu]" -s --durations yes \
      > "$out/gpu_tests.log" 2>&1 || echo "gpu tests: exit $?" >> "$out/gpu_tests.log"
    # polyhedra: the GPU row beside 16 CPU threads (one thread: the docs' table), both laws, the
    # packed settled beds
    timeout 100 .gpu/run.sh poly_throughput "${poly_bed[@]}" --threads 16 --repeat 3 --work 2e6 \
      --law pressure_centre smooth --cache .gpu/poly_cache --json "$out/poly_throughput.json" \
      > "$out/poly_throughput.log" 2>&1 || echo "poly bench: exit $?" >> "$out/poly_throughput.log"
    # throughput: settled beds cached under $out/cache; 10^6 spheres settle on the GPU
    timeout 300 .gpu/run.sh dem_throughput --max-particles 1000000 --threads 1 16 \
      --settle-threads 16 --cache "$out/cache" --json "$out/dem_throughput.json" \
      > "$out/dem_throughput.log" 2>&1 || echo "bench: exit $?" >> "$out/dem_throughput.log"
    rm -rf "$out/cache"  # the beds are large and not needed back
    tail -n 30 "$out/gpu_tests.log" "$out/poly_throughput.log" "$out/dem_throughput.log"
    ;;
  *)
    echo "usage: tools/gpu_session.sh pack|run" >&2
    exit 2
    ;;
esac
