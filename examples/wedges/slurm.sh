#!/bin/bash
# A Slurm array job over the wedges of examples/wedges/words.json (docs/wedges.md): one task per
# wedge, each running the whole simulation of its wedge. The index comes from SLURM_ARRAY_TASK_ID,
# which Slurm sets in every task. words.json has 6 wedges (flockmorph wedge count), so the array
# is 0-5; for another wedge file, size it on the command line, which overrides the line below:
#
#   sbatch --array=0-$(( $(flockmorph wedge count WEDGES.json) - 1 )) examples/wedges/slurm.sh
#
# Submit from the repository root (the paths below are relative to it), with flockmorph built in
# build/. Each task writes out/wedges/words/NNNN/: frames.fmc, stats.json and wedge.json, the
# manifest of what ran.
#SBATCH --job-name=flockmorph-wedges
#SBATCH --array=0-5
#SBATCH --cpus-per-task=4
#SBATCH --mem=4G
#SBATCH --time=00:30:00
#SBATCH --output=out/wedges/slurm-%A_%a.log

set -euo pipefail
mkdir -p out/wedges
exec build/flockmorph run examples/words/scene.json \
    --wedge-file examples/wedges/words.json \
    -o 'out/wedges/{scene}/{wedge}' \
    --threads "${SLURM_CPUS_PER_TASK:-1}" --quiet
