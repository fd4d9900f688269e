#!/usr/bin/env bash
# Runs every bundled example (examples/*/scene.json, and castling's rook.json) with 1 and 2 threads and compares the sha256 of
# its frame cache with tests/data/example-caches.sha256, the bytes the engine wrote before the
# re-layout (issue 12) and every change since that kept behaviour. A change that is meant to alter
# the animation updates the file (--update) in the same commit and says why.
#   tools/check-example-caches.sh [BUILD_DIR]            default BUILD_DIR: build
#   tools/check-example-caches.sh [BUILD_DIR] --update   rewrite the file from this build
# It also checks that every static shape-flock example (deform "none", arrival "bind") ends with every
# agent bound within its frame limit, as stats.json's all_bound says.
# Exit 0 if every cache matches and every static flock binds, 1 otherwise (each failure is named).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${1:-build}
update=0
[ "${2:-}" = --update ] && update=1
cli="$build_dir/flockmorph"
[ -x "$cli" ] || { echo "check-example-caches: no $cli (build first: tools/setup.sh $build_dir)" >&2; exit 1; }
list=tests/data/example-caches.sha256
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

failed=0
new_list=""
# examples/castling/rook.json, the rook's morph alone (the castling benchmarks' scene), as castling_rook.
for scene in examples/*/scene.json examples/castling/rook.json; do
  name=$(basename "$(dirname "$scene")")
  [ "$scene" = examples/castling/rook.json ] && name=castling_rook
  expected=$(awk -v n="$name" '$2 == n {print $1}' "$list")
  first=""
  for threads in 1 2; do
    out="$tmp/$name-$threads"
    if ! "$cli" run "$scene" -o "$out" --threads "$threads" --quiet > "$out.log" 2>&1; then
      echo "FAIL $name ($threads threads): the run failed:"; cat "$out.log"; failed=1; continue
    fi
    if grep -q '"deform": "none"' "$out/stats.json" && grep -q '"arrival_mode": "bind"' "$out/stats.json" &&
       ! grep -q '"all_bound": true' "$out/stats.json"; then
      echo "FAIL $name ($threads threads): a static flock whose agents are not all bound at the frame limit"; failed=1
    fi
    cache=$(find "$out" -maxdepth 1 -name '*.fmc' | head -n 1)
    got=$(sha256sum "$cache" | cut -d' ' -f1)
    [ -z "$first" ] && first=$got
    if [ "$update" = 1 ]; then
      [ "$got" = "$first" ] || { echo "FAIL $name: 1 and 2 threads differ"; failed=1; }
    elif [ "$got" = "$expected" ]; then
      echo "ok   $name ($threads threads) ${got:0:16}"
    else
      echo "FAIL $name ($threads threads): sha256 ${got:0:16}, expected ${expected:0:16}"; failed=1
    fi
  done
  new_list+="$first  $name"$'\n'
done
if [ "$update" = 1 ] && [ "$failed" = 0 ]; then
  printf '%s' "$new_list" > "$list"
  echo "check-example-caches: wrote $list"
fi
[ "$failed" = 0 ] && echo "check-example-caches: every example's cache is byte for byte the recorded one"
exit "$failed"
