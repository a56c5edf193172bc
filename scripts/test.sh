#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite (CPU and GPU tests; Vulkan validation on).
# TERRAVT_SANITIZED=1 then runs the CPU and GPU tests again under AddressSanitizer + UBSan
# (scripts/test-sanitized.sh, build-asan/).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 600
if [ "${TERRAVT_SANITIZED:-0}" = 1 ]; then
  bash scripts/test-sanitized.sh
fi
