#!/usr/bin/env bash
# One command on a fresh Debian 12 machine (as root): install what rubble needs, build it, run
# the default scene. Extra arguments go to `rubble run` (e.g. --end-time 0.2).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DRUBBLE_BUILD_TESTS=OFF -DRUBBLE_BUILD_BENCH=OFF
cmake --build build/release --target rubble _rubble
# The Python module into /usr/bin/python3's site folder (/usr/local/lib/python3.11/dist-packages),
# so that `/usr/bin/python3 -c "import rubble"` works (docs/python.md). Without root:
# PYTHONPATH=build/release/python instead.
cmake --install build/release --component python ||
  echo "demo: could not install the Python module; use: export PYTHONPATH=$PWD/build/release/python"
./build/release/apps/rubble run "$@"
