#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite (CPU and GPU tests; Vulkan validation on).
# Then the CPU and GPU tests again under AddressSanitizer + UBSan (scripts/test-sanitized.sh,
# build-asan/); TERRAVT_SANITIZED=0 skips that second run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 600
if [ "${TERRAVT_SANITIZED:-1}" != 0 ]; then
  bash scripts/test-sanitized.sh
fi
