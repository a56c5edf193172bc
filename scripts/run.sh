#!/usr/bin/env bash
# Sets up, builds and runs the main job on the built-in default scene: a headless flythrough
# through the virtual texture. Frames and per-frame stats go to out/render/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
mkdir -p out
# --overwrite: each run replaces the previous run's frames and stats in out/render.
./build/tools/terravt render --out out/render --overwrite "$@"
echo "frames and stats.jsonl in out/render/"
