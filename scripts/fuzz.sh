#!/usr/bin/env bash
# Builds the scene-parser fuzz target with clang (libFuzzer + AddressSanitizer + UBSan, in its own
# CMake configuration build/fuzz) and runs it for SECONDS (default 60) from a seed corpus of every
# scene file in the repository. Exits non-zero if libFuzzer finds a crash, a sanitizer report, an
# exception other than SceneError, a timeout or an out-of-memory; the input that did it is saved
# as build/fuzz/crash-* (or timeout-*, oom-*). See fuzz/README.md.
#
# usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
build=build/fuzz

mkdir -p "$build"
CXX=clang++ CC=clang cmake -S fuzz -B "$build" -G Ninja > "$build/configure.log" 2>&1 ||
  { cat "$build/configure.log"; exit 1; }
cmake --build "$build" --target fuzz_scene_parser -j "$(nproc)"

seeds="$build/seeds"
corpus="$build/corpus"
rm -rf "$seeds" "$corpus" && mkdir -p "$seeds" "$corpus"
# Seeds: the small scenes of the tests (the examples include runs of 10^4 polyhedra, too slow to
# replay under the sanitizers in a 60 s budget; box-deposit.toml is the default scene).
find tests -name '*.toml' -exec cp {} "$seeds/" \;
cp examples/box-deposit.toml "$seeds/"
echo "fuzz: $(ls "$seeds" | wc -l) seed scenes, ${seconds} s"

# -seed: a fixed mutation sequence (RUBBLE_FUZZ_SEED, default 1; 0 = random), so a CI run explores
# a reproducible prefix of it and a failure can be replayed; longer local runs should use 0.
# -timeout: one input may take at most 30 s (the parser expands generators: a scene of 10^6 grains
# is legitimate work, not a hang); -rss_limit_mb: the scene-file limits keep memory below this.
cd "$build"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ./fuzz_scene_parser -seed="${RUBBLE_FUZZ_SEED:-1}" -max_total_time="$seconds" -timeout=30 -rss_limit_mb=6144 -max_len=16384 \
  -dict=../../fuzz/scene.dict -print_final_stats=1 corpus seeds
