#!/usr/bin/env bash
# Strong scaling on one many-core machine without Open MPI installed: flockmorph and Open MPI from
# the bundle tools/device-bundle.sh packs. Runs the scenes of tools/bench-ranks.sh (castling's rook
# as a tetra morph, every agent launched at once; the shape flock from Suzanne to the torus,
# randomly sampled; 2 steps a frame) as P ranks x T threads, checks every cache is byte-identical to
# the mode's first one, and writes a line a run to OUTDIR/scaling.txt (and stdout) as it completes,
# and every record so far to OUTDIR/scaling.json. Stops starting runs when the time left is short:
# the whole script ends within FM_SCALING_BUDGET seconds (420).
#   bash tools/bench-scaling.sh BUNDLE_TARBALL OUTDIR          (from the repository root)
# Overrides (environment): FM_SCALING_N (both modes' n), FM_SCALING_TETRA_N, FM_SCALING_FLOCK_N,
#   FM_SCALING_TETRA_STEPS, FM_SCALING_FLOCK_STEPS (2 a frame), FM_SCALING_RUNS ("16x1 1x16 ..."),
#   FM_SCALING_PLIST ("1 2": P x 1 for each P, in that order), FM_SCALING_MODES ("tetra flock"),
#   FM_SCALING_BUDGET (seconds), FM_SCALING_TETRA_SHARE (of the budget the tetra runs may use).
set -uo pipefail
start=$SECONDS
[ $# = 2 ] || { echo "usage: bash tools/bench-scaling.sh BUNDLE_TARBALL OUTDIR" >&2; exit 2; }
tarball=$(readlink -f "$1") outdir=$2
cd "$(dirname "$0")/.." || exit 1
[ -f "$tarball" ] || { echo "bench-scaling: no $tarball" >&2; exit 1; }
mkdir -p "$outdir"
outdir=$(readlink -f "$outdir")
txt=$outdir/scaling.txt json=$outdir/scaling.json
: > "$txt"
budget=${FM_SCALING_BUDGET:-420}
margin=8 # seconds kept back at the end: a timed-out run's clean-up, the summary

# Everything goes to stdout and, at once, to scaling.txt.
say() { printf '%s\n' "$*" | tee -a "$txt"; }

work=$(mktemp -d /tmp/fm-scaling.XXXXXX)
trap 'rm -rf "$work"' EXIT
# Unpack before env.sh puts the bundle's libraries on LD_LIBRARY_PATH.
mkdir -p "$work/bundle"
if command -v xz > /dev/null; then
  tar -xJf "$tarball" -C "$work/bundle" || { say "bench-scaling: cannot unpack $tarball"; exit 1; }
elif command -v python3 > /dev/null; then
  python3 -c 'import sys, tarfile; tarfile.open(sys.argv[1], "r:xz").extractall(sys.argv[2])' \
    "$tarball" "$work/bundle" || { say "bench-scaling: cannot unpack $tarball"; exit 1; }
else
  say "bench-scaling: neither xz nor python3 to unpack $tarball"; exit 1
fi
# shellcheck source=/dev/null
source "$work/bundle/env.sh"
export OMP_WAIT_POLICY=passive # as tools/bench-ranks.sh
cli=$work/bundle/bin/flockmorph

tetra_n=${FM_SCALING_TETRA_N:-${FM_SCALING_N:-1000000}}
flock_n=${FM_SCALING_FLOCK_N:-${FM_SCALING_N:-}}
tetra_steps=${FM_SCALING_TETRA_STEPS:-60}
flock_steps=${FM_SCALING_FLOCK_STEPS:-}
if [ -n "${FM_SCALING_RUNS:-}" ]; then
  runs=$FM_SCALING_RUNS
elif [ -n "${FM_SCALING_PLIST:-}" ]; then
  runs=$(for p in $FM_SCALING_PLIST; do printf '%sx1 ' "$p"; done)
else
  runs="16x1 16x1/one 1x16 8x1 4x1 2x1 1x1 4x4"
fi
modes=${FM_SCALING_MODES:-tetra flock}
tetra_share=${FM_SCALING_TETRA_SHARE:-0.5}

cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
say "flockmorph strong scaling, $(date -u +%Y-%m-%dT%H:%M:%SZ): $cpu, nproc $(nproc), $(grep -c ^processor /proc/cpuinfo) logical CPUs; $("$cli" --version); $(mpirun --version 2>&1 | head -1)"
say "tetra: examples/castling/rook.json, n=$tetra_n, launch_rate=1e9, mde.d_min=0.0063, $tetra_steps steps, 2 a frame (time_step=1/48)"
say "flock: examples/flock_suzanne_torus/scene.json, n=${flock_n:-(chosen below)}, shape_flock.sampling=random, ${flock_steps:-(chosen below)} steps, 2 a frame (time_step=1/48)"
say "runs: $runs (PxT: P ranks of T threads; P>1 as mpirun --bind-to none -np P; 1xT without mpirun; /one: the cache in one piece, output.piece_agents=2^30, so rank 0 encodes every frame alone); modes: $modes; budget ${budget} s"
say "wall: the run's wall seconds (start-up and preprocessing included); pre/sim/out: stats.json preprocess/simulate/output_seconds; bytes, halo: per agent-step; imb: load_imbalance (agents in flight), busy: busy_imbalance (the ranks' own work in their steps); migr: migrations; peak: the largest rank's peak resident MiB (P>1)"
# A small job on 2 ranks first: does mpirun work, and may vader copy with CMA (a container may
# forbid process_vm_readv)? Else without single copy.
copy=""
for mech in ${FM_SCALING_SINGLE_COPY:-${OMPI_MCA_btl_vader_single_copy_mechanism:-cma} none}; do
  export OMPI_MCA_btl_vader_single_copy_mechanism=$mech
  rm -rf "$work/probe"
  if timeout --kill-after=5 60 mpirun --bind-to none -np 2 "$cli" run examples/castling/rook.json -o "$work/probe" \
    --threads 1 --quiet --set n=20000 --set time.frame_limit=3 > "$work/probe.log" 2>&1; then copy=$mech; break; fi
  say "probe: mpirun -np 2 failed with btl_vader_single_copy_mechanism=$mech:"
  tail -n 5 "$work/probe.log" | sed 's/^/    | /' | tee -a "$txt"
done
rm -rf "$work/probe"
[ -n "$copy" ] || { say "bench-scaling: mpirun does not work here; nothing measured"; exit 1; }
say "probe: mpirun -np 2 works, btl_vader_single_copy_mechanism=$copy, shared memory in ${OMPI_MCA_btl_vader_backing_directory:-/dev/shm}; $((SECONDS - start)) s so far"
hdr=$(printf '%-5s %-5s %7s %7s %7s %7s %8s %7s %5s %5s %9s %6s  %s' mode PxT wall pre sim out bytes halo imb busy migr peak cache)
say "$hdr"

records=()
write_json() {
  { printf '[\n'; local i; for i in "${!records[@]}"; do
      [ "$i" -gt 0 ] && printf ',\n'; printf '  %s' "${records[$i]}"; done; printf '\n]\n'; } > "$json.part"
  mv "$json.part" "$json"
}
write_json

# stats.json (pretty-printed, a key a line) to "pre sim out bytes halo imb busy migr peak" (- where absent).
stats_fields() {
  awk '
    /^  "scale_out": \{/ { so = 1; next }
    so && /^  \}/ { so = 0 }
    { line = $0; sub(/,[ \t]*$/, "", line) }
    !so && match(line, /^  "(preprocess_seconds|simulate_seconds|output_seconds)": /) {
      k = line; sub(/^  "/, "", k); sub(/".*/, "", k); v = line; sub(/^[^:]*: /, "", v); f[k] = v }
    so && match(line, /^    "(bytes_sent_per_agent_step|halo_agents_per_agent_step|load_imbalance|busy_imbalance|migrations|max_rank_peak_rss_bytes)": /) {
      k = line; sub(/^    "/, "", k); sub(/".*/, "", k); v = line; sub(/^[^:]*: /, "", v); f[k] = v }
    END {
      n = split("preprocess_seconds simulate_seconds output_seconds bytes_sent_per_agent_step halo_agents_per_agent_step load_imbalance busy_imbalance migrations max_rank_peak_rss_bytes", keys, " ")
      for (i = 1; i <= n; i++) printf "%s%s", (keys[i] in f ? f[keys[i]] : "-"), (i < n ? " " : "\n")
    }' "$1"
}
num() { [ "$1" = - ] && printf null || printf '%s' "$1"; }
fmt() { if [ "$1" = - ]; then printf %s -; else LC_ALL=C awk -v v="$1" -v f="$2" 'BEGIN { printf f, v }'; fi; }

# Estimated wall seconds of a run, from one core of a 2-core x86-64 VM (AMD EPYC, 2026-12-04), at
# 10^6 agents and 60 steps: tetra 1x1 17 s quiet, 25-28 s with the other core busy (preprocess
# 3.0-4.2, simulate 10.6-20, output 0.9-1.8); flock 1x1 68 s quiet, 82 s busy (preprocess 1.0-1.1,
# simulate 60-73, output 4.8-5.7). On 2 ranks output took 2.5-7 times as long (rank 0 gathers,
# checks and writes every frame while the others wait); every rank preprocesses, on one thread,
# whatever T; comparing and deleting the cache (about 1 GB at 10^6 agents) takes about 1.5 s.
# Rescaled by the ratio of the time the mode's runs so far took to their estimates.
declare -A est_pre est_sim est_out scale sum_wall sum_est
est_pre[tetra]=${FM_EST_TETRA_PRE:-3.5} est_sim[tetra]=${FM_EST_TETRA_SIM:-13} est_out[tetra]=${FM_EST_TETRA_OUT:-1.3}
est_pre[flock]=${FM_EST_FLOCK_PRE:-1.1} est_sim[flock]=${FM_EST_FLOCK_SIM:-64} est_out[flock]=${FM_EST_FLOCK_OUT:-5}
raw_estimate() { # mode n p t steps: seconds, unscaled
  LC_ALL=C awk -v pre="${est_pre[$1]}" -v sim="${est_sim[$1]}" -v out="${est_out[$1]}" -v n="$2" \
    -v p="$3" -v t="$4" -v steps="$5" 'BEGIN {
      f = n / 1e6; c = p * t
      w = 3 + 1.5 * f + pre * f * (p > 1 ? 1.5 : 1) + sim * f * steps / 60 / c * (c > 1 ? 1.2 : 1) + out * f * steps / 60 * (p > 1 ? 2.5 : 1)
      printf "%.2f", w }'
}
estimate() { # mode n p t steps: seconds, scaled to this machine
  LC_ALL=C awk -v w="$(raw_estimate "$@")" -v s="${scale[$1]:-1}" 'BEGIN { printf "%d", s * w + 1 }'
}
for mode in $modes; do
  case $mode in
    tetra) scene=examples/castling/rook.json n=$tetra_n steps=$tetra_steps
      extra=(--set launch_rate=1e9 --set mde.d_min=0.0063)
      deadline=$(LC_ALL=C awk -v b="$budget" -v s="$tetra_share" -v m="$modes" 'BEGIN { printf "%d", (m ~ /flock/ ? b * s : b) }') ;;
    flock) scene=examples/flock_suzanne_torus/scene.json
      extra=(--set shape_flock.sampling=random)
      deadline=$budget
      # Unless set, the largest of 10^6 agents x 60 steps, 10^6 x 30 and 2*10^5 x 60 whose runs
      # all fit in 90 % of the time left (estimates rescaled by the tetra runs' calibration).
      [ -n "${scale[tetra]:-}" ] && [ -z "${scale[flock]:-}" ] && scale[flock]=${scale[tetra]}
      for cand in "1000000 60" "1000000 30" "200000 60"; do
        n=${flock_n:-${cand% *}} steps=${flock_steps:-${cand#* }}
        total=0
        for run in $runs; do r=${run%/*}; total=$((total + $(estimate flock "$n" "${r%x*}" "${r#*x}" "$steps"))); done
        [ $((10 * total)) -le $((9 * (deadline - margin - (SECONDS - start)))) ] && break
      done
      unset 'scale[flock]'
      say "flock: n=$n, $steps steps (frame_limit $((steps / 2 + 1))); all its runs estimated at $total s, $((deadline - margin - (SECONDS - start))) s left"
      if [ "$n" != 1000000 ] || [ "$steps" != 60 ]; then
        why="to fit the time budget"; [ -n "$flock_n$flock_steps" ] && why="as FM_SCALING_* set"
        say "note: the flock runs at n=$n, $steps steps, not 10^6 and 60 (tools/bench-ranks.sh), $why"
      fi ;;
    *) say "bench-scaling: mode is tetra or flock, not $mode"; continue ;;
  esac
  sets=(--set n="$n" --set time.time_step=0.02083333333333333 --set time.frame_limit=$((steps / 2 + 1)) "${extra[@]}")
  ref=""
  for run in $runs; do
    variant=""; [ "${run#*/}" != "$run" ] && variant=${run#*/}
    p=${run%%x*} t=${run#*x}; t=${t%/*}
    one=(); [ "$variant" = one ] && one=(--set output.piece_agents=1073741824)
    elapsed=$((SECONDS - start))
    est=$(estimate "$mode" "$n" "$p" "$t" "$steps")
    left=$((budget - margin - elapsed))
    if [ $((deadline - margin - elapsed)) -lt "$est" ] || [ "$left" -lt 10 ]; then
      say "$(printf '%-5s %-5s skipped: time (%d s elapsed, about %d s needed, %d s left for %s)' "$mode" "$run" "$elapsed" "$est" $((deadline - margin - elapsed)) "$mode")"
      records+=("{\"mode\": \"$mode\", \"ranks\": $p, \"threads\": $t, \"n\": $n, \"steps\": $steps, \"status\": \"skipped: time\", \"estimated_seconds\": $est}")
      write_json
      continue
    fi
    # A run may overrun its estimate by far (a slower machine) but never the whole budget.
    limit=$((3 * est + 30)); [ "$limit" -gt "$left" ] && limit=$left
    rm -rf "$work/run"
    if [ "$p" = 1 ]; then
      cmd=("$cli" run "$scene" -o "$work/run" --threads "$t" --quiet --overwrite "${sets[@]}" "${one[@]}")
    else
      cmd=(mpirun --bind-to none -np "$p" "$cli" run "$scene" -o "$work/run" --threads "$t" --quiet --overwrite "${sets[@]}" "${one[@]}")
    fi
    t0=$(date +%s.%N)
    timeout --kill-after=5 "$limit" "${cmd[@]}" > "$work/log" 2>&1
    rc=$?
    wall=$(LC_ALL=C awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')
    if [ "$rc" = 0 ] && [ -f "$work/run/stats.json" ]; then status=ok; else status="failed (exit $rc)"; fi
    [ "$rc" = 124 ] || [ "$rc" = 137 ] && status="timeout (${limit} s)"
    read -r pre sim out bytes halo imb busy migr peak < <( [ -f "$work/run/stats.json" ] && stats_fields "$work/run/stats.json" || echo "- - - - - - - - -")
    peak_mib=-; [ "$peak" != - ] && peak_mib=$(LC_ALL=C awk -v b="$peak" 'BEGIN { printf "%.0f", b / 1048576 }')
    cache=none
    if [ "$status" = ok ] && [ -f "$work/run/frames.fmc" ]; then
      if [ -n "$variant" ]; then cache="$variant piece"
      elif [ -z "$ref" ]; then ref=$work/ref-$mode.fmc; mv "$work/run/frames.fmc" "$ref"; cache="reference"
      elif cmp -s "$ref" "$work/run/frames.fmc"; then cache=identical
      else cache=DIFFERENT; fi
    fi
    line=$(printf '%-5s %-5s %7s %7s %7s %7s %8s %7s %5s %5s %9s %6s  %s' "$mode" "$run" "$wall" \
      "$(fmt "$pre" %.2f)" "$(fmt "$sim" %.2f)" "$(fmt "$out" %.2f)" "$(fmt "$bytes" %.1f)" \
      "$(fmt "$halo" %.4f)" "$(fmt "$imb" %.3f)" "$(fmt "$busy" %.3f)" "$migr" "$peak_mib" "$cache")
    [ "$status" = ok ] || line="$line  $status"
    say "$line"
    if [ "$status" != ok ]; then tail -n 5 "$work/log" | sed 's/^/    | /' | tee -a "$txt"; fi
    records+=("{\"mode\": \"$mode\", \"ranks\": $p, \"threads\": $t, \"variant\": \"$variant\", \"n\": $n, \"steps\": $steps, \"status\": \"$status\", \"wall_seconds\": $wall, \"estimated_seconds\": $est, \"preprocess_seconds\": $(num "$pre"), \"simulate_seconds\": $(num "$sim"), \"output_seconds\": $(num "$out"), \"scale_out\": {\"bytes_sent_per_agent_step\": $(num "$bytes"), \"halo_agents_per_agent_step\": $(num "$halo"), \"load_imbalance\": $(num "$imb"), \"busy_imbalance\": $(num "$busy"), \"migrations\": $(num "$migr"), \"max_rank_peak_rss_bytes\": $(num "$peak")}, \"cache\": \"$cache\"}")
    write_json
    rm -rf "$work/run"
    # The mode's runs so far calibrate the estimates of the rest to this machine.
    if [ "$status" = ok ]; then
      took=$(LC_ALL=C awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')
      sum_wall[$mode]=$(LC_ALL=C awk -v a="${sum_wall[$mode]:-0}" -v b="$took" 'BEGIN { print a + b }')
      sum_est[$mode]=$(LC_ALL=C awk -v a="${sum_est[$mode]:-0}" -v b="$(raw_estimate "$mode" "$n" "$p" "$t" "$steps")" 'BEGIN { print a + b }')
      scale[$mode]=$(LC_ALL=C awk -v w="${sum_wall[$mode]}" -v e="${sum_est[$mode]}" 'BEGIN {
        s = w / e; if (s < 0.3) s = 0.3; if (s > 3) s = 3; printf "%.3f", s }')
    fi
  done
  rm -f "$work/ref-$mode.fmc"
done

# Speed-ups against the mode's 1x1 run, where there is one.
say "speed-up over 1x1 where 1x1 ran: simulate, simulate+output, wall"
for r in "${records[@]}"; do printf '%s\n' "$r"; done | LC_ALL=C awk '
  function get(k,   v) { v = $0; if (!sub(".*\"" k "\": ", "", v)) return ""; sub(/[,}].*/, "", v); return v }
  get("status") != "\"ok\"" { next }
  { m = get("mode"); gsub(/"/, "", m); v = get("variant"); gsub(/"/, "", v); key = m " " get("ranks") "x" get("threads") (v != "" ? "/" v : "")
    k[++nk] = key; M[nk] = m; S[key] = get("simulate_seconds"); O[key] = get("output_seconds"); W[key] = get("wall_seconds")
    if (get("ranks") == 1 && get("threads") == 1 && v == "") { bs[m] = S[key]; bo[m] = O[key]; bw[m] = W[key] } }
  END { for (i = 1; i <= nk; i++) { m = M[i]; key = k[i]
      if (!(m in bs)) { printf "  %-11s (no 1x1 run)\n", key; continue }
      printf "  %-11s %6.2f %6.2f %6.2f\n", key, bs[m] / S[key], (bs[m] + bo[m]) / (S[key] + O[key]), bw[m] / W[key] } }' | tee -a "$txt"
say "done in $((SECONDS - start)) s"
