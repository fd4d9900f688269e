#!/usr/bin/env bash
# Renders the pictures of README.md and docs/scenarios.md (docs/images/*.png) with
# `flockmorph render`, from runs of the bundled scenes into out/NAME/ (run afresh, so that a cache
# an older engine or scene left there is not drawn; they take about 10 s together).
#   tools/readme-images.sh
set -euo pipefail
cd "$(dirname "$0")/.."
tools/setup.sh build > /dev/null
scenes=(words moon creatures castling)
for name in "${scenes[@]}"; do
  build/flockmorph run "examples/$name/scene.json" -o "out/$name" --quiet --overwrite > /dev/null
done
# --color id: their captions say the colour follows the launch order (the agent id), which is what
# render drew before --color speed became its default. --camera frame: each frame's own camera, as
# these pictures were made before the whole-shot camera became the default (a later --camera wins).
render() { build/flockmorph render "out/$1/frames.fmc" --size 800x400 --samples 2 --color id --camera frame "${@:2}" > /dev/null; }
# README: the words example at frames 0, 30, 60, 90 and its last frame.
for k in 0 30 60 90; do render words --frame "$k" -o "docs/images/words_$k.png"; done
render words --frame -1 -o docs/images/words_last.png
# docs/scenarios.md: each scenario 40 % of the way through (the frame run-scenarios.sh previews);
# the whole castling at 60 %, while the rook passes the king (at 40 % the king has just formed).
for name in "${scenes[@]}"; do
  frames=$(sed -n 's/^  "frames": \([0-9]*\),*$/\1/p' "out/$name/stats.json")
  k=$((frames * 2 / 5)); [ "$name" = castling ] && k=$((frames * 3 / 5))
  render "$name" --frame "$k" -o "docs/images/scenario_$name.png"
done
# docs/shape-flock.md "A target that travels": flock_travel forming, formed, gliding and stopped, one
# camera over the whole run.
build/flockmorph run examples/flock_travel/scene.json -o out/flock_travel --quiet --overwrite > /dev/null
for k in 150 215 300 404; do
  build/flockmorph render out/flock_travel/frames.fmc --frame "$k" -o "docs/images/flock_travel_$k.png" --view persp \
    --size 480x270 --samples 2 --camera animation --color speed --color-range 0:12 > /dev/null
done
# docs/scenarios.md, "A target that moves": walking_suzanne formed at rest (frame 119, t = 4.96 s, the
# motion starts at 5 s), then breathing and walking off: one camera over the whole run for the walk,
# and each frame's own camera for the breath and the nod.
build/flockmorph run examples/walking_suzanne/scene.json -o out/walking_suzanne --quiet --overwrite > /dev/null
for k in 119 200 287; do render walking_suzanne --frame "$k" --camera animation -o "docs/images/walking_suzanne_wide_$k.png"; done
for k in 119 150 200 250; do render walking_suzanne --frame "$k" -o "docs/images/walking_suzanne_$k.png"; done
echo "docs/images: ${#scenes[@]} scenarios, 5 frames of words, 4 of flock_travel and 7 of walking_suzanne rendered"
