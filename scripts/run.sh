#!/usr/bin/env bash
# Sets up, builds and runs the main job on the built-in default scene; output goes to out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
mkdir -p out
./build/tools/terravt compose --out out/compose.png "$@"
echo "wrote out/compose.png"
