#!/usr/bin/env bash
# Sets up (installs what is missing, builds) and runs a bundled example scene.
#   tools/run-example.sh [NAME]        NAME is a folder of examples/ (default: words)
# Writes out/NAME/frames.fmc, out/NAME/stats.json and a preview PNG of the last frame.
set -euo pipefail
cd "$(dirname "$0")/.."
name=${1:-words}
[ -f "examples/$name/scene.json" ] || { echo "no example named '$name' (see examples/)" >&2; exit 1; }
tools/setup.sh build > /dev/null
out="out/$name"
build/flockmorph run "examples/$name/scene.json" -o "$out" --overwrite
build/flockmorph render "$out/frames.fmc" --frame -1 -o "$out/last.png" > /dev/null
echo "preview: $out/last.png"
