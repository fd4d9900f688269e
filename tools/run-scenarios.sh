#!/usr/bin/env bash
# Runs every bundled scenario (the paper's Table I) and prints a Markdown table of our figures.
#   tools/run-scenarios.sh [THREADS [OUTDIR]]   (default: all cores, ${TMPDIR:-/tmp}/flockmorph-scenarios)
# Writes OUTDIR/<name>/ for each scene, plus a preview PNG of a mid-flight frame. OUTDIR is outside
# the source tree unless given, so a run leaves the checkout as it was.
set -euo pipefail
threads=${1:-$(nproc)}
out=$(realpath -m "${2:-${TMPDIR:-/tmp}/flockmorph-scenarios}") # before the cd: a relative OUTDIR is the caller's
cd "$(dirname "$0")/.."
mkdir -p "$out"
tools/setup.sh build > /dev/null
stat() { sed -n "s/^  \"$2\": \\([^,]*\\),*$/\\1/p" "$out/$1/stats.json"; }
echo "| scenario | agents | frames | steps | preprocess s | steps/s | agent-steps/s | MDE % | min clearance | min vertex clearance | all arrived |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"
# castling's row is the rook's morph (examples/castling/rook.json), the one FM Table I times; the
# example's scene.json is the whole two-part castling (docs/scenarios.md).
for name in words moon creatures castling_rook; do
  scene="examples/$name/scene.json"
  [ "$name" = castling_rook ] && scene=examples/castling/rook.json
  build/flockmorph run "$scene" -o "$out/$name" --threads "$threads" --quiet --overwrite > /dev/null
  frames=$(stat "$name" frames)
  build/flockmorph render "$out/$name/frames.fmc" --frame $((frames * 2 / 5)) --size 800x400 -o "$out/$name/mid.png" > /dev/null
  steps=$(stat "$name" steps); sim=$(stat "$name" simulate_seconds)
  awk -v n="$name" -v a="$(stat "$name" agents)" -v f="$frames" -v s="$steps" -v p="$(stat "$name" preprocess_seconds)" \
      -v t="$sim" -v r="$(stat "$name" agent_steps_per_second)" -v m="$(stat "$name" mde_fraction_mean)" \
      -v c="$(stat "$name" min_obstacle_clearance)" -v vc="$(stat "$name" min_vertex_clearance)" \
      -v ok="$(stat "$name" all_arrived)" \
      'BEGIN { printf "| %s | %d | %d | %d | %.2f | %.0f | %.3g | %.2f | %s | %s | %s |\n", n, a, f, s, p, s / t, r, 100 * m, c, vc, ok }'
done
echo "run-scenarios: the caches, stats and previews are in $out/" >&2
