#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz with clang, ASan and UBSan in build-fuzz/ and runs each
# for SECONDS (default 60) on its corpus (docs/testing.md). Exits non-zero when a target crashes,
# leaks, hangs or runs out of memory, and prints the input that did it.
#   tools/fuzz.sh [SECONDS [TARGET...]]     TARGET: scene, cache, mesh, ply_binary, stl_binary (default: all)
# New inputs libFuzzer finds go to build-fuzz/work/TARGET/corpus, not into the repository.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene cache mesh ply_binary stl_binary)

FM_EXTRA_PACKAGES="clang-14 libclang-rt-14-dev libomp-14-dev" CC=clang-14 CXX=clang++-14 \
  FM_BUILD_TYPE=RelWithDebInfo tools/setup.sh build-fuzz -DFM_FUZZ=ON -DBUILD_TESTING=OFF

# assimp's own leaks on damaged files are not the engine's (tests/fuzz/lsan.supp says which).
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp"
failed=0
for t in "${targets[@]}"; do
  work=build-fuzz/work/$t
  mkdir -p "$work/corpus" "$work/artifacts"
  args=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1
        -artifact_prefix="$work/artifacts/")
  [ -f "tests/fuzz/$t.dict" ] && args+=(-dict="tests/fuzz/$t.dict")
  inputs=("$work/corpus" "tests/fuzz/corpus/$t")
  [ -d "tests/fuzz/regressions/$t" ] && inputs+=("tests/fuzz/regressions/$t")
  echo "fuzz_$t: ${seconds} s (log: $work/log)"
  start=$(date +%s)
  if build-fuzz/tests/fuzz/"fuzz_$t" "${args[@]}" "${inputs[@]}" > "$work/log" 2>&1; then
    grep -E "^stat::number_of_executed_runs|^#[0-9]+.*DONE" "$work/log" | tail -2 || true
    echo "fuzz_$t: ok after $(( $(date +%s) - start )) s"
  else
    failed=1
    grep -E "^==[0-9]+==ERROR|^SUMMARY|FUZZ_ASSERT|unclean|runtime error" "$work/log" | head -5 || true
    for a in "$work"/artifacts/*; do [ -e "$a" ] && echo "fuzz_$t: FAILED on input $a"; done
  fi
done
exit $failed
