#!/usr/bin/env bash
# Configures a clang build with AddressSanitizer and UndefinedBehaviorSanitizer and the scene
# parser's fuzz target (fuzz/README.md): the one configuration that scripts/test.sh (build/sanitize,
# with the tests) and scripts/fuzz.sh (build/fuzz, libraries only) both build.
#
# usage: scripts/configure-sanitizer.sh BUILD_DIR [more cmake -D options]
#
# -O1 and line tables only (-g1): reports still give file and line, and the build compiles in less
# than half the time of -O2 -g (GCC, tests/nlgs_solver/test_nlgs.cpp: 24 s against 52 s). The
# Python module is left out (a sanitized extension cannot be loaded by a plain /usr/bin/python3
# without LD_PRELOAD of the sanitizer runtimes), and so are the benchmarks and the CUDA backend.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: scripts/configure-sanitizer.sh BUILD_DIR [cmake options]}
shift

# A cache keeps its compiler and source folder: a build made by GCC, or by the former separate
# fuzz/ project, cannot be turned into this one. Start it again.
cache=$build/CMakeCache.txt
if [ -f "$cache" ] && ! { grep -q '^CMAKE_CXX_COMPILER:FILEPATH=.*clang++' "$cache" &&
  grep -q "^CMAKE_HOME_DIRECTORY:INTERNAL=$PWD\$" "$cache"; }; then
  rm -rf "$build"
fi
CXX=clang++ CC=clang cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DRUBBLE_SANITIZE=address,undefined -DRUBBLE_BUILD_FUZZ=ON -DRUBBLE_BUILD_BENCH=OFF \
  -DRUBBLE_BUILD_PYTHON=OFF -DRUBBLE_GRAVITY_CUDA=OFF "$@"
