#!/usr/bin/env bash
# Installs the Debian packages flockmorph needs (only those missing), then configures and builds.
#   tools/setup.sh [BUILD_DIR [extra cmake arguments...]]      default BUILD_DIR: build
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build}
shift || true

# One package a line, so additions merge cleanly.
packages=(
  build-essential
  cmake
  pkg-config
  libtet1.5-dev
  libassimp-dev
  libjansson-dev
  libzstd-dev
  zlib1g-dev
  libpng-dev
  libembree-dev
  libopenvdb-dev
  libtbb-dev
  libblosc-dev
  libboost-iostreams-dev
  python3
  python3-numpy
  python3-zstandard
  python3-venv
  python3-pip
  python3-setuptools
  python3-wheel
  libxxhash-dev
  ffmpeg
  libopenmpi-dev
  openmpi-bin
  libcivetweb-dev
  nodejs
  npm
  chromium
  jq # test_wedge reads a wedge's seed back with jq (and Node), as a pipeline would (docs/wedges.md)
)
# Debian's Blender 3.4 runs the add-on's test (tests/blender/test_blender_import.py). With
# --no-install-recommends it is 31 packages, a 70 MiB download and 270 MiB installed (Debian 12),
# so it comes only when the tests need it: tools/run-tests.sh sets FM_WITH_BLENDER=1
# (FM_WITH_BLENDER=0 leaves it out, and the test reports SKIPPED). FM_WITH_BLENDER=1
# tools/setup.sh installs it for using the add-on.
if [ "${FM_WITH_BLENDER:-0}" = 1 ]; then
  packages+=(blender)
fi
# Debian's VTK 9.1 for Python reads the .vtu export back in tests/io/test_vtk_reader.py, the
# reader ParaView uses. With --no-install-recommends it is 27 packages, a 36 MB download and
# 185 MiB installed (Debian 12, Qt 5 included), so, like Blender, it comes only when the tests
# need it: tools/run-tests.sh sets FM_WITH_VTK=1 (FM_WITH_VTK=0 leaves it out, and the test
# reports SKIPPED).
if [ "${FM_WITH_VTK:-0}" = 1 ]; then
  packages+=(python3-vtk9)
fi
# The peers tools/bench-peers.sh runs beside bench_suite (docs/performance.md, "Peers"): LAMMPS
# (its LJ benchmark) and Blender (its boids); and matplotlib for the benchmark plots
# (tools/plot_bench.py, tools/plot_density.py). Only on request, FM_WITH_PEERS=1: CI needs none.
if [ "${FM_WITH_PEERS:-0}" = 1 ]; then
  packages+=(lammps blender python3-matplotlib)
fi
# Packages a calling script needs besides these (tools/fuzz.sh and tools/run-tsan.sh: clang).
read -r -a extra_packages <<< "${FM_EXTRA_PACKAGES:-}"
packages+=("${extra_packages[@]}")
missing=()
for p in "${packages[@]}"; do
  # A Node from elsewhere (NodeSource's nodejs carries its own npm, and conflicts with Debian's)
  # serves as well: the page needs node >= 18 and npm, not Debian's packages of them.
  case $p in nodejs|npm) command -v "${p/nodejs/node}" > /dev/null && continue ;; esac
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# What it does goes to stderr, a line a step, so a caller that hides the build's output
# (tools/run-example.sh) still shows progress on a fresh machine.
say() { echo "flockmorph setup: $*" >&2; }
start=$SECONDS
if [ ${#missing[@]} -gt 0 ]; then
  say "installing ${#missing[@]} Debian packages with apt-get: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The studio's page (docs/studio.md): its npm packages exactly as web/package-lock.json pins them,
# again only when the lockfile changed (npm ci starts from an empty node_modules). From npm's cache
# where it has them, so a machine that ran this once builds the page offline.
if [ ! web/node_modules/.package-lock.json -nt web/package-lock.json ]; then
  say "installing the studio page's npm packages (npm ci in web/)"
  (cd web && npm ci --prefer-offline --no-audit --no-fund --loglevel=error) >&2
fi

mkdir -p "$build_dir"
say "configuring $build_dir/ (${FM_BUILD_TYPE:-Release}; log: $build_dir/cmake-configure.log)"
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE="${FM_BUILD_TYPE:-Release}" "$@" > "$build_dir/cmake-configure.log" 2>&1 \
  || { cat "$build_dir/cmake-configure.log"; exit 1; }
[ -x "$build_dir/flockmorph" ] || say "building $build_dir/ on $(nproc) cores: a first build takes about a minute on 2 cores (65 s Release, 77 s with the sanitizers, measured on a 2-vCPU Xeon)"
cmake --build "$build_dir" -j"$(nproc)"
say "ready in $((SECONDS - start)) s: $build_dir/flockmorph"
