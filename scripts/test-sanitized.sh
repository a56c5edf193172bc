#!/usr/bin/env bash
# Builds the suite with AddressSanitizer + UBSan into build-asan/ (no fuzzers) and runs the CPU
# and GPU tests there; any sanitizer report fails its test. Settings: tests/sanitizers.env,
# leak suppressions (dependencies only): tests/lsan.supp. Run by scripts/test.sh with
# TERRAVT_SANITIZED=1. To run ctest in build-asan by hand, export the same settings first.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$(pwd)"
start=$(date +%s)
mkdir -p build-asan
# Before the settings are exported: LD_PRELOAD names it.
cc -shared -fPIC -O2 -o build-asan/libtvt_no_dlclose.so tests/no_dlclose.c
# The build needs them too: gtest_discover_tests runs the sanitized test binaries.
while IFS= read -r line; do
  case "$line" in [A-Z]*=*) export "${line//@SOURCE_DIR@/$root}" ;; esac
done < tests/sanitizers.env
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTERRAVT_SANITIZE=ON -DTERRAVT_BUILD_FUZZERS=OFF >/dev/null
cmake --build build-asan -j"$(nproc)"
built=$(date +%s)
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 1200 -L 'cpu|gpu'
echo "sanitized build $((built - start)) s, tests $(($(date +%s) - built)) s"
