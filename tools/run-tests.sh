#!/usr/bin/env bash
# Sets up (installs what is missing, builds) and runs the whole test suite with ctest.
#   tools/run-tests.sh                 Release build in build/
#   FM_SANITIZE=1 tools/run-tests.sh   AddressSanitizer + UndefinedBehaviorSanitizer build in build-asan/
#   FM_WITH_BLENDER=0 tools/run-tests.sh   without installing Blender (test_blender is then skipped)
#   FM_WITH_VTK=0 tools/run-tests.sh       without installing VTK's Python (test_vtk_reader is then skipped)
set -euo pipefail
cd "$(dirname "$0")/.."
export FM_WITH_BLENDER=${FM_WITH_BLENDER:-1} # setup.sh installs Blender for test_blender
export FM_WITH_VTK=${FM_WITH_VTK:-1}         # and python3-vtk9 for test_vtk_reader
if [ "${FM_SANITIZE:-0}" = 1 ]; then
  FM_BUILD_TYPE=Debug tools/setup.sh build-asan -DFM_SANITIZE=ON -DFM_WERROR=ON
  dir=build-asan
else
  tools/setup.sh build -DFM_WERROR=ON
  dir=build
fi
# ctest runs tests side by side, each with OpenMP threads: more threads than cores. Spinning at
# OpenMP barriers (libgomp's default) then burns the cores the other tests need; sleeping does not.
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}"
# The sanitizer pass leaves the look's measures on whole scenes (label "look") to the Release pass.
exclude=()
if [ "${FM_SANITIZE:-0}" = 1 ]; then exclude=(-LE look); fi
ctest --test-dir "$dir" --output-on-failure -j"$(nproc)" "${exclude[@]}"
