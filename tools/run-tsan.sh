#!/usr/bin/env bash
# Builds build-tsan/ with ThreadSanitizer (clang-14 and LLVM's libomp) and runs the threaded tests:
# those with OpenMP steps or the cache writer thread (docs/testing.md).
#   tools/run-tsan.sh [CTEST_REGEX]
# GCC's libgomp is not instrumented, so TSan cannot see its barriers and reports races between an
# OpenMP region and the code after it. LLVM's libomp loads its archer tool (OMPT) when the program
# runs under TSan, and archer tells TSan about every OpenMP barrier, lock and task; no suppression
# is needed. ignore_noninstrumented_modules skips accesses made inside uninstrumented libraries
# (libomp, zstd, TBB, Embree) themselves; the engine's own code is always checked.
set -euo pipefail
cd "$(dirname "$0")/.."
tests=${1:-'^(test_e2e|test_cache|test_examples|test_grid|test_velocity_e2e|test_obstacles|test_fields)$'}

FM_EXTRA_PACKAGES="clang-14 libomp-14-dev" CC=clang-14 CXX=clang++-14 \
  FM_BUILD_TYPE=RelWithDebInfo tools/setup.sh build-tsan -DFM_TSAN=ON

reports=$PWD/build-tsan/tsan-reports
rm -rf "$reports" && mkdir -p "$reports"
export OMP_TOOL_LIBRARIES=/usr/lib/llvm-14/lib/libarcher.so
# Reports of the tests and of the CLI they start go to files, so none is lost in a child's log.
export TSAN_OPTIONS="ignore_noninstrumented_modules=1 log_path=$reports/report second_deadlock_stack=1"
status=0
ctest --test-dir build-tsan -R "$tests" --output-on-failure || status=1
if compgen -G "$reports/report*" > /dev/null; then
  echo "run-tsan: ThreadSanitizer reports (all of them in $reports/):"
  grep -h "^SUMMARY" "$reports"/report* | sort | uniq -c
  echo "run-tsan: the first one:"
  awk '/^==================$/ && seen++ == 1 {exit} {print}' $(ls "$reports"/report* | head -1)
  status=1
fi
[ $status -eq 0 ] && echo "run-tsan: no data races"
exit $status
