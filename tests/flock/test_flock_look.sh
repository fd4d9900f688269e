#!/usr/bin/env bash
# The shape flock's look, measured from the cache by tools/flock-look.py (issue 37), independently of
# the engine's statistics, on examples/flock_cylinder_sphere as shipped (every flock key at its
# default): at mid-flight neighbour persistence, neighbour coherence and acceleration smoothness,
# over the whole run no common dead stop; with the three rules x4 (SCF Figure 7) still a smooth,
# coherent flock, not noise; and every agent bound within the frame limit. Then two scenes the rules
# were not tuned on (tests/flock/scenes: moon -> star on a bent path, king -> torus on a straight
# one): coherence, smoothness, no dead stop, all bound; their persistence is printed, not asserted
# (0.36 and 0.53 of the issue's 0.6: issue 37's open part, docs/shape-flock.md).
#   test_flock_look.sh CLI OUT_DIR PYTHON3 (Debian's, with numpy)
set -euo pipefail
cli=$1 out=$2 python=${3:-/usr/bin/python3}
cd "$(dirname "$0")/../.."
scene=examples/flock_cylinder_sphere/scene.json
look=("$python" tools/flock-look.py)
rm -rf "$out"
"$cli" run "$scene" -o "$out/on" --quiet --threads 2
"${look[@]}" "$out/on/frames.fmc" --check persistence=0.6,coherence=0.6,smoothness=0.5,dead_stop=0.1
grep -q '"all_bound": *true' "$out/on/stats.json" || { echo "test_flock_look: not every agent bound" >&2; exit 1; }
"$cli" run "$scene" -o "$out/x4" --quiet --threads 2 --set 'shape_flock.separation.weight=[1.6,2.4]' \
  --set 'shape_flock.cohesion.weight=[0.4,0.8]' --set 'shape_flock.alignment.weight=[8,12]'
"${look[@]}" "$out/x4/frames.fmc" --check persistence=0.5,coherence=0.6,smoothness=0.5,dead_stop=0.1
for name in moon_star king_torus; do
  "$cli" run "tests/flock/scenes/$name.json" -o "$out/$name" --quiet --threads 2
  "${look[@]}" "$out/$name/frames.fmc" --check coherence=0.6,smoothness=0.5,dead_stop=0.1 | grep -E '^(persistence|dead_stop) '
  grep -q '"all_bound": *true' "$out/$name/stats.json" || { echo "test_flock_look: $name: not every agent bound" >&2; exit 1; }
done
echo "test_flock_look: passed"
