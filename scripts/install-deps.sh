#!/usr/bin/env bash
# Installs every Debian 12 package rubble needs to build, test and post-process.
# Idempotent and non-interactive: packages already present are not reinstalled, and
# `apt-get update` only runs when something is missing. Run as root (or with sudo).
set -euo pipefail

packages=(
  # toolchain
  build-essential cmake ninja-build pkg-config git
  # numerics and geometry
  libeigen3-dev      # small fixed-size vectors/matrices (Vec3, 3x3 Delassus blocks)
  libcgal-dev        # convex hulls of random points for polyhedral grains
  libomp-dev         # OpenMP runtime (gcc ships libgomp; clang builds need this)
  # input / output
  libhdf5-dev hdf5-tools   # run output, checkpoints, FCLib problems
  libvtk9-dev        # ParaView (.vtu/.pvd) output
  libtomlplusplus-dev # scene files (TOML, with line numbers in errors)
  libcli11-dev       # command-line parsing
  nlohmann-json3-dev # one-line JSON reports
  libfmt-dev         # formatting (g++ 12 has no std::format)
  # tests and benchmarks
  libgtest-dev libgmock-dev googletest libbenchmark-dev
  libsiconos-numerics-dev   # the reference FCLib solver (Siconos NSGS) for bench_siconos
  clang libclang-rt-14-dev  # the sanitizer build of the test gate, libFuzzer, their runtimes
  clang-format clang-tidy   # the code style (.clang-format) and static checks (.clang-tidy)
  # post-processing and output checks in tests
  python3 python3-numpy python3-h5py python3-matplotlib python3-vtk9
  # the Python module `rubble` (python/): bindings, headers, its tests, sparse W and rotations
  pybind11-dev python3-pybind11 python3-dev python3-pytest python3-scipy
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
# In CI (.ci/run sets RUBBLE_CI=1, on a throw-away machine) dpkg skips its fsync calls: the
# installation took 85 -> 68 s here (the packages already downloaded). Not on a workstation, where a
# crash during the installation would leave damaged packages.
dpkg_options=()
if [ "${RUBBLE_CI:-0}" = 1 ]; then dpkg_options=(-o Dpkg::Options::=--force-unsafe-io); fi
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${dpkg_options[@]}" "${missing[@]}" >/dev/null
echo "install-deps: done"
