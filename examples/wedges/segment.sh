#!/bin/bash
# One segment of a run split into farm tasks under a time limit (docs/wedges.md, "A run longer
# than a task"): continues the run in OUTDIR from its checkpoint when there is one, or starts it,
# and stops after frame END with the checkpoint kept (exit 0). A run that ends before END just
# finishes; once it has finished (OUTDIR/stats.json, no checkpoint), a later segment does nothing.
#
#   examples/wedges/segment.sh SCENE OUTDIR END [flockmorph run options ...]
#
# FLOCKMORPH names the binary (default: build/flockmorph, from the repository root).
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: segment.sh SCENE OUTDIR END [flockmorph run options ...]" >&2
  exit 1
fi
scene=$1 out=$2 end=$3
shift 3
cli=${FLOCKMORPH:-build/flockmorph}
if [ -e "$out/checkpoint.fmck" ]; then
  exec "$cli" run "$scene" -o "$out" --resume --stop-after-frame "$end" "$@"
fi
if [ -e "$out/stats.json" ]; then
  echo "segment.sh: $out holds a finished run: nothing to do"
  exit 0
fi
exec "$cli" run "$scene" -o "$out" --stop-after-frame "$end" "$@"
