#!/usr/bin/env bash
# One command on a fresh Debian 12 machine (as root): install what rubble needs, build it, run
# the default scene. Extra arguments go to `rubble run` (e.g. --end-time 0.2).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DRUBBLE_BUILD_TESTS=OFF -DRUBBLE_BUILD_BENCH=OFF
cmake --build build/release --target rubble
./build/release/apps/rubble run "$@"
