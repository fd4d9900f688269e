#!/usr/bin/env bash
# 1 rank x T threads (no mpirun) against P ranks x 1 thread, alternated, at 10^6 agents
# (docs/scale-out.md): castling's rook with every agent launched at once, or (MODE flock) the shape
# flock from Suzanne to the torus, randomly sampled. Prints simulate and output seconds of each run,
# their ratios and the scale_out figures; checks the caches are byte-identical.
#   tools/bench-ranks.sh [BUILD_DIR] [ROUNDS] [P] [STEPS_PER_FRAME] [MODE]   defaults: build 3 2 2 morph
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} rounds=${2:-3} ranks=${3:-2} spf=${4:-2} mode=${5:-morph}
cli="$build/flockmorph"
[ -x "$cli" ] || { echo "bench-ranks: no $cli (build first: tools/setup.sh $build)" >&2; exit 1; }
command -v mpirun > /dev/null || { echo "bench-ranks: no mpirun (Open MPI: tools/setup.sh installs it)" >&2; exit 1; }
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
export OMP_WAIT_POLICY=passive
dt=$(awk -v s="$spf" 'BEGIN { printf "%.17g", 1 / (24 * s) }')
sets=(--set n=1000000 --set time.time_step="$dt" --set time.frame_limit=$((60 / spf + 1)))
case $mode in
  morph) scene=examples/castling/rook.json name="castling's rook"; sets+=(--set launch_rate=1e9 --set mde.d_min=0.0063) ;;
  flock) scene=examples/flock_suzanne_torus/scene.json name="the shape flock"; sets+=(--set shape_flock.sampling=random) ;;
  *) echo "bench-ranks: MODE is morph or flock, not $mode" >&2; exit 2 ;;
esac
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "$name, 10^6 agents, $((60 / spf)) frames of $spf steps; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) cores"
for round in $(seq 1 "$rounds"); do
  rm -rf "$tmp/a" "$tmp/b"
  "$cli" run "$scene" -o "$tmp/a" --threads "$ranks" --quiet --overwrite "${sets[@]}" > /dev/null
  mpirun --oversubscribe ${FM_MPIRUN_OPTIONS:-} -np "$ranks" "$cli" run "$scene" -o "$tmp/b" --threads 1 --quiet --overwrite "${sets[@]}" > /dev/null
  cmp -s "$tmp/a/frames.fmc" "$tmp/b/frames.fmc" && same=identical || same=DIFFERENT
  /usr/bin/python3 - "$tmp/a/stats.json" "$tmp/b/stats.json" "$round" "$ranks" "$same" <<'PY'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
r, p, same = sys.argv[3], sys.argv[4], sys.argv[5]
sa, oa, sb, ob = a["simulate_seconds"], a["output_seconds"], b["simulate_seconds"], b["output_seconds"]
so = b.get("scale_out", {})
print(f"round {r}: 1x{p} simulate {sa:.2f} s output {oa:.2f} s | {p}x1 simulate {sb:.2f} s output {ob:.2f} s | "
      f"(1x{p})/({p}x1) simulate {sa / sb:.3f} total {(sa + oa) / (sb + ob):.3f} | caches {same} | "
      f"bytes/agent-step {so.get('bytes_sent_per_agent_step', 0):.1f} halo/agent-step {so.get('halo_agents_per_agent_step', 0):.4f} "
      f"imbalance {so.get('load_imbalance', 0):.3f} busy {so.get('busy_imbalance', 0):.3f} migrations {so.get('migrations', 0)} "
      f"largest rank's peak {so.get('max_rank_peak_rss_bytes', 0) / 2**20:.0f} MiB")
PY
done
