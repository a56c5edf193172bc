#!/usr/bin/env bash
# Sets up, builds and runs the whole test suite (CPU and GPU tests; Vulkan validation on).
# In CI (CI=true) or with TERRAVT_SANITIZED=1 it then runs the CPU and GPU tests again under
# AddressSanitizer + UBSan (scripts/test-sanitized.sh, build-asan/); TERRAVT_SANITIZED=0 skips
# that, in CI too.
set -euo pipefail
cd "$(dirname "$0")/.."
sanitized=${TERRAVT_SANITIZED:-0}
if [ -z "${TERRAVT_SANITIZED:-}" ] && [ "${CI:-}" = true ]; then sanitized=1; fi
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 600
if [ "$sanitized" = 1 ]; then
  bash scripts/test-sanitized.sh
fi
