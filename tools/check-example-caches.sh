#!/usr/bin/env bash
# Runs every bundled example (examples/*/scene.json, and castling's rook.json) with 1 and 2 threads and compares the sha256 of
# its frame cache with tests/data/example-caches.sha256, the bytes the engine wrote before the
# re-layout (issue 12) and every change since that kept behaviour. A change that is meant to alter
# the animation updates the file (--update) in the same commit and says why.
#   tools/check-example-caches.sh [BUILD_DIR]                  default BUILD_DIR: build
#   tools/check-example-caches.sh [BUILD_DIR] --update         rewrite the file from this build
#   tools/check-example-caches.sh [BUILD_DIR] --runs-from DIR  hash the runs other tests left in DIR
# --runs-from: a run of an example that another test already made, exactly as this script makes it
# (`run SCENE -o OUT --threads T --quiet`, nothing else, as its stats.json's command_line says, on one
# rank), with
# a complete cache newer than BUILD_DIR's CLI, somewhere under DIR, is hashed instead of run again.
# ctest passes build/tests/tmp, where test_examples and the look tests leave their runs
# (tests/CMakeLists.txt orders them before this one); any run not found there is made here.
# It also checks that every static shape-flock example (deform "none", arrival "bind") ends with every
# agent bound within its frame limit, as stats.json's all_bound says.
# Exit 0 if every cache matches and every static flock binds, 1 otherwise (each failure is named).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=build
[ $# -gt 0 ] && [ "${1:0:2}" != -- ] && { build_dir=$1; shift; }
update=0 runs_from=""
case "${1:-}" in
  "") ;;
  --update) update=1 ;;
  --runs-from) runs_from=${2:?check-example-caches: --runs-from needs a folder} ;;
  *) echo "check-example-caches: unknown option $1 (--update or --runs-from DIR)" >&2; exit 1 ;;
esac
cli="$build_dir/flockmorph"
[ -x "$cli" ] || { echo "check-example-caches: no $cli (build first: tools/setup.sh $build_dir)" >&2; exit 1; }
list=tests/data/example-caches.sha256
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# A file's identity: inode, size, modification time. A run reused from another test is hashed only
# if its cache is the same file after the hash as when it was found (no test has made it again meanwhile).
identity() { stat -c '%i:%s:%Y' "$1" 2>/dev/null || true; }

# Lines "SCENE_ABSOLUTE<TAB>THREADS<TAB>OUTDIR<TAB>IDENTITY" for the finished plain runs under
# $runs_from: one rank (not a rank of an mpirun job, whose command line is the same), the command
# line, once "-o OUT" is taken out, is "run SCENE --threads T --quiet" (either order), the cache is
# complete (no .partial beside it) and newer than the CLI.
index_runs() {
  [ -n "$runs_from" ] && [ -d "$runs_from" ] || return 0
  find "$runs_from" -maxdepth 4 -name stats.json -newer "$cli" -print0 |
    while IFS= read -r -d '' stats; do
      dir=$(dirname "$stats")
      [ -f "$dir/frames.fmc" ] && [ ! -e "$dir/frames.fmc.partial" ] && [ "$dir/frames.fmc" -nt "$cli" ] || continue
      jq -r --arg dir "$dir" --arg id "$(identity "$dir/frames.fmc")" '
        (.command_line[1:]) as $a | ($a | index("-o")) as $o
        | select($o != null) | ($a[:$o] + $a[$o + 2:]) as $r
        | select(($r | length) == 5 and $r[0] == "run" and .ranks == 1)
        | select($r[2:] == ["--threads", ($r[3]), "--quiet"] or $r[2:] == ["--quiet", "--threads", ($r[4])])
        | [.scene_absolute, (if $r[2] == "--threads" then $r[3] else $r[4] end), $dir, $id] | @tsv' "$stats" 2>/dev/null || true
    done
}
index_runs > "$tmp/runs.tsv"

# "OUTDIR<TAB>IDENTITY" of a plain run of scene $1 at $2 threads under $runs_from (none: empty).
reusable_run() { awk -F'\t' -v s="$1" -v t="$2" '$1 == s && $2 == t {print $3 "\t" $4; exit}' "$tmp/runs.tsv"; }

# Prints a failure if the run in $1 is a static flock (deform "none", arrival "bind") whose agents
# are not all bound at its frame limit.
check_static_flock() {
  if grep -q '"deform": "none"' "$1/stats.json" && grep -q '"arrival_mode": "bind"' "$1/stats.json" &&
     ! grep -q '"all_bound": true' "$1/stats.json"; then
    echo "a static flock whose agents are not all bound at the frame limit"
  fi
}

failed=0 reused=0 runs=0
new_list=""
# examples/castling/rook.json, the rook's morph alone (the castling benchmarks' scene), as castling_rook.
for scene in examples/*/scene.json examples/castling/rook.json; do
  name=$(basename "$(dirname "$scene")")
  [ "$scene" = examples/castling/rook.json ] && name=castling_rook
  expected=$(awk -v n="$name" '$2 == n {print $1}' "$list")
  first=""
  for threads in 1 2; do
    runs=$((runs + 1))
    IFS=$'\t' read -r out id <<< "$(reusable_run "$(realpath "$scene")" "$threads")" || true
    got="" from=""
    if [ -n "$out" ]; then
      got=$(sha256sum < "$out/frames.fmc" | cut -d' ' -f1)
      flock=$(check_static_flock "$out")
      if [ "$(identity "$out/frames.fmc")" = "$id" ]; then
        reused=$((reused + 1)) from=" (the run in ${out#"$runs_from"/})"
      else
        got=""
      fi
    fi
    if [ -z "$got" ]; then
      out="$tmp/$name-$threads"
      if ! "$cli" run "$scene" -o "$out" --threads "$threads" --quiet > "$out.log" 2>&1; then
        echo "FAIL $name ($threads threads): the run failed:"; cat "$out.log"; failed=1; continue
      fi
      got=$(sha256sum < "$out/frames.fmc" | cut -d' ' -f1)
      flock=$(check_static_flock "$out")
    fi
    [ -z "$flock" ] || { echo "FAIL $name ($threads threads): $flock$from"; failed=1; }
    [ -z "$first" ] && first=$got
    if [ "$update" = 1 ]; then
      [ "$got" = "$first" ] || { echo "FAIL $name: 1 and 2 threads differ"; failed=1; }
    elif [ "$got" = "$expected" ]; then
      echo "ok   $name ($threads threads) ${got:0:16}$from"
    else
      echo "FAIL $name ($threads threads): sha256 ${got:0:16}, expected ${expected:0:16}$from"; failed=1
    fi
  done
  new_list+="$first  $name"$'\n'
done
[ -n "$runs_from" ] && echo "check-example-caches: $reused of $runs runs taken from $runs_from, $((runs - reused)) run here"
if [ "$update" = 1 ] && [ "$failed" = 0 ]; then
  printf '%s' "$new_list" > "$list"
  echo "check-example-caches: wrote $list"
fi
[ "$failed" = 0 ] && echo "check-example-caches: every example's cache is byte for byte the recorded one"
exit "$failed"
