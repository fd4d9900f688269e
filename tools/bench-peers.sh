#!/usr/bin/env bash
# flockmorph's throughput beside what its users would run instead, alternated in the same minutes
# (docs/performance.md, "Peers"):
#
#   tools/bench-peers.sh [--build DIR] [--rounds R] [--agents N] [--flock-agents N] [--steps S]
#
# Each round runs, one after the other:
#   - bench_suite's tetra morph (--agents N, default 10^6, 2 threads and 1),
#   - LAMMPS's Lennard-Jones benchmark (bench/in.lj: 32,000 atoms, 100 steps; Debian's lammps,
#     `lmp`) on 1 rank and on 2 ranks (mpirun),
#   - bench_suite's shape flock (--mode flock --sampling random --agents N, default 10^5),
#   - Blender's boids (bench/blender_boids.py, Debian's blender) at the flock's agent count,
# and prints each run's agent-steps (atom-steps) per second, then a Markdown table of the medians
# and min-max over the rounds. A peer that is not installed is reported and left out:
# `FM_WITH_PEERS=1 tools/setup.sh` installs LAMMPS (and Blender), which CI does not need.
#
# Exit status: 0 done; 1 usage; 2 a run failed.
set -euo pipefail
cd "$(dirname "$0")/.."

usage() {
    sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
}
die() { echo "bench-peers: $1" >&2; exit "${2:-1}"; }

build=build rounds=2 agents=1000000 flock_agents=100000 steps=10
while [ $# -gt 0 ]; do
    case $1 in
    --build) build=${2:?}; shift 2 ;;
    --rounds) rounds=${2:?}; shift 2 ;;
    --agents) agents=${2:?}; shift 2 ;;
    --flock-agents) flock_agents=${2:?}; shift 2 ;;
    --steps) steps=${2:?}; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) usage >&2; die "unknown option $1" ;;
    esac
done
for v in rounds agents flock_agents steps; do
    [[ ${!v} =~ ^[1-9][0-9]*$ ]] || die "--${v//_/-} takes a positive integer, not '${!v}'"
done
[ -x "$build/bench_suite" ] || die "no $build/bench_suite: build it first (cmake --build $build --target bench_suite)"

export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
if [ "$(id -u)" = 0 ]; then export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
results=$tmp/results.tsv # workload, threads or ranks, agent-steps/s
: > "$results"

lmp=$(command -v lmp || command -v lmp_serial || true)
blender=$(command -v blender || true)
[ -n "$lmp" ] || echo "bench-peers: LAMMPS (lmp) is not installed: FM_WITH_PEERS=1 tools/setup.sh installs it; left out" >&2
[ -n "$blender" ] || echo "bench-peers: Blender is not installed: FM_WITH_PEERS=1 tools/setup.sh installs it; left out" >&2

# bench_suite's JSON: the 2-thread and 1-thread agent-steps/s of its first run.
suite() { # LABEL ARGS...
    local label=$1; shift
    "$build/bench_suite" "$@" --machine 0 > "$tmp/suite.json" 2> "$tmp/suite.err" || { cat "$tmp/suite.err" >&2; die "bench_suite $* failed" 2; }
    /usr/bin/python3 - "$tmp/suite.json" "$label" >> "$results" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))["runs"][0]
print(f"{sys.argv[2]}\t{r['threads']}\t{r['agent_steps_per_second']:.4g}")
print(f"{sys.argv[2]}\t1\t{r['one_thread']['agent_steps_per_second']:.4g}")
EOF
}

# LAMMPS's "Loop time of T on P procs for S steps with A atoms".
lammps() { # RANKS
    local ranks=$1 cmd=("$lmp" -in in.lj -log none -screen "$tmp/lammps.out")
    [ "$ranks" -gt 1 ] && cmd=(mpirun -np "$ranks" "${cmd[@]}")
    (cd "$tmp" && OMP_NUM_THREADS=1 "${cmd[@]}" > /dev/null 2> "$tmp/lammps.err") || { cat "$tmp/lammps.err" >&2; die "LAMMPS on $ranks rank(s) failed" 2; }
    awk -v r="$ranks" '/^Loop time of/ { printf "LAMMPS LJ, 32,000 atoms\t%s\t%.4g\n", r, $12 * $9 / $4 }' "$tmp/lammps.out" >> "$results"
}

boids() {
    "$blender" -b --factory-startup --python bench/blender_boids.py -- "$flock_agents" 5 > "$tmp/boids.out" 2>&1 \
        || { tail -20 "$tmp/boids.out" >&2; die "Blender's boids failed" 2; }
    /usr/bin/python3 - "$tmp/boids.out" >> "$results" <<'EOF'
import json, sys
for line in open(sys.argv[1]):
    if line.startswith('{"peer"'):
        r = json.loads(line)
        print(f"Blender {r['blender']} boids, {r['agents']:,}\tauto\t{r['agent_steps_per_second']:.4g}")
EOF
}

cp bench/in.lj "$tmp/in.lj"
echo "bench-peers: $(date -u '+%Y-%m-%d %H:%M UTC'), $rounds round(s)"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) CPUs; load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
for ((r = 1; r <= rounds; r++)); do
    before=$(wc -l < "$results")
    suite "tetra morph, $agents agents" --agents "$agents" --steps "$steps" --threads 2
    if [ -n "$lmp" ]; then lammps 1; lammps 2; fi
    suite "shape flock, $flock_agents agents" --mode flock --sampling random --agents "$flock_agents" --steps "$steps" --threads 2
    [ -n "$blender" ] && boids
    echo "round $r/$rounds (load average $(cut -d' ' -f1 /proc/loadavg)):"
    tail -n +"$((before + 1))" "$results" | awk -F'\t' '{ printf "  %-40s %5s  %s agent-steps/s\n", $1, $2, $3 }'
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
/usr/bin/python3 - "$results" <<'EOF'
import statistics, sys
rows = {}
for line in open(sys.argv[1]):
    work, threads, rate = line.rstrip("\n").split("\t")
    rows.setdefault((work, threads), []).append(float(rate))
print("| workload | threads or ranks | agent-steps/s: median (min-max) |")
print("| --- | ---: | ---: |")
for (work, threads), rates in rows.items():
    spread = f" ({min(rates):.3g}-{max(rates):.3g})" if len(rates) > 1 else ""
    print(f"| {work} | {threads} | {statistics.median(rates):.3g}{spread} |")
EOF
