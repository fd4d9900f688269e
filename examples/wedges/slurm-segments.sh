#!/bin/bash
# Submits one long run as a chain of Slurm jobs, each a segment that fits the partition's time
# limit and starts once the previous one succeeded (docs/wedges.md, "A run longer than a task"):
#
#   examples/wedges/slurm-segments.sh SCENE OUTDIR FRAMES SEGMENTS [flockmorph run options ...]
#
# Segment k (0, 1, ...) writes frames up to (k + 1) FRAMES - 1 (examples/wedges/segment.sh); the
# last one runs to the end, however many frames that takes. Submit from the repository root, with
# flockmorph built in build/. CPUS (default 4) and TIME (default 01:00:00) size each job.
set -euo pipefail
if [ $# -lt 4 ]; then
  echo "usage: slurm-segments.sh SCENE OUTDIR FRAMES SEGMENTS [flockmorph run options ...]" >&2
  exit 1
fi
scene=$1 out=$2 frames=$3 segments=$4
shift 4
cpus=${CPUS:-4}
# Slurm opens each job's --output before the job runs: its folder must exist now
mkdir -p "$(dirname "$out")"
previous=
for ((k = 0; k < segments; k++)); do
  end=$(( k + 1 < segments ? (k + 1) * frames - 1 : 2000000000 ))
  command=$(printf '%q ' examples/wedges/segment.sh "$scene" "$out" "$end" --threads "$cpus" --quiet "$@")
  job=$(sbatch --parsable --job-name="flockmorph-segment-$k" --cpus-per-task="$cpus" --time="${TIME:-01:00:00}" \
        --output="$out.segment-$k.log" ${previous:+--dependency=afterok:$previous} --wrap "$command")
  echo "segment $k: job $job, frames up to $end"
  previous=$job
done
