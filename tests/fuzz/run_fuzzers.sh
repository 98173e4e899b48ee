#!/usr/bin/env bash
# Builds the fuzz harnesses with clang + libFuzzer + ASan + UBSan and runs each for a while.
# NDEBUG as in the shipped build: toml++ 3.3 has a debug assertion in parse_key() that input
# like tests/fuzz/corpus/scene/toml_parse_key_assert.toml trips, while its release build
# rejects that input cleanly (checked under valgrind by the replay test).
# New crashing inputs land in fuzz-out/<target>/ (to be fixed and then copied into
# tests/fuzz/corpus/<target>/ as regression inputs, which ctest replays).
#
#   tests/fuzz/run_fuzzers.sh [SECONDS_PER_TARGET] [TARGET...]     (default 600 s; all)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
seconds="${1:-600}"
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(scene inp stl csv h5)
out="$root/fuzz-out"
mkdir -p "$out"

flags=(-std=c++20 -O1 -g -Wno-pass-failed -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
  -DTOML_HEADER_ONLY=1 -DNDEBUG -I"$root/protocol/scene/include" -I"$root/protocol/io/include"
  -I"$root/protocol/interface/include" -I"$root/fem_server/include" -I"$root/fem_server/src"
  -I"$root/dem_server/include" -I"$root/dem_server/src" -I/usr/include/eigen3
  -I/usr/include/hdf5/serial)

sources_for() {
  case "$1" in
    scene) echo "$root/protocol/scene/scene_reader.cpp $root/protocol/scene/scene_override.cpp $root/protocol/io/input_file.cpp" ;;
    inp) echo "$root/protocol/scene/scene_reader.cpp $root/protocol/scene/scene_override.cpp $root/protocol/io/input_file.cpp $(for f in reader deck model step; do echo "$root/fem_server/src/io/inp_$f.cpp"; done)" ;;
    stl) echo "$root/protocol/io/input_file.cpp $(ls "$root"/dem_server/src/tools/stl_reader*.cpp 2>/dev/null)" ;;
    csv | h5) ls "$out"/obj-dem/*.o ;;
  esac
}

# The particle readers need the whole DEM library (its systems load and step the particles):
# compiled once per call of this script, on every core, for both particle targets.
dem_objects_built=0
build_dem_objects() {
  local obj="$out/obj-dem" src o n=0
  if [ "$dem_objects_built" = 0 ]; then
    rm -rf "$obj" && mkdir -p "$obj"
    for src in "$root"/dem_server/src/{core,shapes,tools}/*.cpp "$root"/protocol/io/*.cpp \
      "$root"/protocol/scene/*.cpp; do
      o="$obj/$(echo "${src#"$root"/}" | tr / _).o"
      clang++ "${flags[@]/-fsanitize=fuzzer,/-fsanitize=fuzzer-no-link,}" -fopenmp=libgomp -c "$src" \
        -o "$o" >&2 &
      if (((++n) % $(nproc) == 0)); then wait; fi
    done
    wait
    dem_objects_built=1
  fi
}

for t in "${targets[@]}"; do
  harness="$root/tests/fuzz/fuzz_$t.cpp"
  [ -f "$harness" ] || { echo "no harness for $t"; continue; }
  libs=()
  case "$t" in csv | h5) build_dem_objects && libs=(-fopenmp=libgomp -lhdf5_serial -lqhull_r) ;; esac
  # shellcheck disable=SC2046
  clang++ "${flags[@]}" "$harness" $(sources_for "$t") "${libs[@]}" -o "$out/fuzz_$t"
  mkdir -p "$out/$t/corpus" "$out/$t/crashes"
  cp -n "$root/tests/fuzz/corpus/$t/"* "$out/$t/corpus/" 2>/dev/null || true
  echo "fuzzing $t for $seconds s"
  "$out/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
    -artifact_prefix="$out/$t/crashes/" "$out/$t/corpus" 2>&1 | tail -n 5
done
