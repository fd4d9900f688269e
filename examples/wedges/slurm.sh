#!/bin/bash
# A Slurm array job over the wedges of examples/wedges/words.json (docs/wedges.md): one task per
# wedge, each running the whole simulation of its wedge. The index comes from SLURM_ARRAY_TASK_ID,
# which Slurm sets in every task. words.json has 6 wedges (flockmorph wedge count), so the array
# is 0-5. Submit from the repository root (the paths below are relative to it), with flockmorph
# built in build/, by running the script itself:
#
#   examples/wedges/slurm.sh                      # makes out/wedges/logs, then sbatch's this file
#   examples/wedges/slurm.sh --array=0-$(( $(build/flockmorph wedge count WEDGES.json) - 1 ))
#
# Run by hand it creates the log folder first and submits itself with its logs there: Slurm opens
# a task's --output file before the script starts, so a folder the script made would come too
# late, and on a fresh checkout the task would fail with no log at all. Its arguments go to sbatch
# (they override the #SBATCH lines). Given straight to sbatch, the logs go to the folder sbatch
# was run in, which exists. Each task writes out/wedges/words/NNNN/: frames.fmc, stats.json and
# wedge.json, the manifest of what ran.
#SBATCH --job-name=flockmorph-wedges
#SBATCH --array=0-5
#SBATCH --cpus-per-task=4
#SBATCH --mem=4G
#SBATCH --time=00:30:00
#SBATCH --output=flockmorph-wedges-%A_%a.log

set -euo pipefail
if [ -z "${SLURM_JOB_ID:-}" ]; then # by hand, not a task: submit this file
  mkdir -p out/wedges/logs
  exec sbatch --output='out/wedges/logs/slurm-%A_%a.log' "$@" "$0"
fi
exec build/flockmorph run examples/words/scene.json \
    --wedge-file examples/wedges/words.json \
    -o 'out/wedges/{scene}/{wedge}' \
    --threads "${SLURM_CPUS_PER_TASK:-1}" --quiet
