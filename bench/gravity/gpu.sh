#!/usr/bin/env bash
# The GPU gravity checks and figures (bench/RESULTS.md, "GPU gravity"), for a machine with an
# NVIDIA GPU, nvcc and CMake but none of rubble's Debian packages: builds gravity/ alone with its
# CUDA backend and its tests (Google Test from the sources in GTEST_SOURCE when none is installed),
# runs the gravity tests, then bench_gravity on the CPU (all cores) and on the GPU.
#   bench/gravity/gpu.sh [OUT_DIR]    (from the repository root; GTEST_SOURCE=dir, CUDA_ARCH=90)
set -uo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
OUT="${1:-$ROOT/build/gpu-results}"
BUILD="${BUILD:-$ROOT/build/gravity-gpu}"
GTEST_SOURCE="${GTEST_SOURCE:-$ROOT/build/device/googletest}"
CUDA_ARCH="${CUDA_ARCH:-90}"
cores=$(nproc)
mkdir -p "$OUT"
{
  echo "# $(date -u) | $(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>&1)"
  echo "# host: $(lscpu | grep 'Model name' | sed 's/ \+/ /g'), $cores cores; load $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "# nvcc: $(nvcc --version | tail -1); c++: $(c++ --version | head -1)"
} | tee "$OUT/machine.txt"
cmake -S "$ROOT/gravity" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CUDA_ARCHITECTURES="$CUDA_ARCH" -DRUBBLE_GRAVITY_GTEST_SOURCE="$GTEST_SOURCE" > "$OUT/configure.log" 2>&1 ||
  { tail -30 "$OUT/configure.log"; exit 1; }
cmake --build "$BUILD" -j "$cores" > "$OUT/build.log" 2>&1 || { grep -B2 -A10 -m5 error "$OUT/build.log"; exit 1; }
echo "== tests"
timeout 240 ctest --test-dir "$BUILD" -j 4 --output-on-failure > "$OUT/ctest.log" 2>&1
echo "ctest exit $?"
grep -E "tests passed|tests failed|Failed|\*\*\*" "$OUT/ctest.log" | head -20
"$BUILD/tests/gravity/test_gravity_cuda" > "$OUT/test_cuda.log" 2>&1
grep -E "^\[  (PASSED|FAILED|SKIPPED)|OK \]|FAILED \]" "$OUT/test_cuda.log"
echo "== compute-sanitizer (memcheck, racecheck) on the small GPU tree test"
for tool in memcheck racecheck; do
  timeout 120 compute-sanitizer --tool "$tool" "$BUILD/tests/gravity/test_gravity_cuda" \
    --gtest_filter='Cuda.TreeHandles*' > "$OUT/sanitizer_$tool.log" 2>&1
  echo "$tool exit $?: $(grep -E 'ERROR SUMMARY|RACECHECK SUMMARY' "$OUT/sanitizer_$tool.log" | tail -1)"
done
bench="$BUILD/bench/gravity/bench_gravity"
echo "== direct sum"
timeout 90 "$bench" --direct-rate --n 100000 --backend cpu,cuda --threads "$cores" --reps 2 | tee "$OUT/direct.md"
timeout 60 "$bench" --direct-rate --n 1000000 --backend cuda --reps 2 | tail -1 | tee -a "$OUT/direct.md"
for dist in uniform plummer; do
  echo "== tree, $dist, theta 0.5 quadrupole, CPU ($cores threads) against the GPU"
  timeout 240 "$bench" --dist "$dist" --n 100000,1000000,10000000 --theta 0.5 --order 2 --backend cpu,cuda \
    --threads "$cores" --reps 2 --csv "$OUT/tree_$dist.csv" | tee "$OUT/tree_$dist.md"
done
echo "== tree on the GPU, uniform 10^6, theta and order"
timeout 120 "$bench" --dist uniform --n 1000000 --theta 0.3,0.5,0.7,1.0 --order 1,2 --backend cuda \
  --threads "$cores" --reps 2 --csv "$OUT/tree_theta.csv" | tee "$OUT/tree_theta.md"
echo "# load at the end: $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/machine.txt"
