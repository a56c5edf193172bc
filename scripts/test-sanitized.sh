#!/usr/bin/env bash
# Builds the suite with AddressSanitizer + UBSan into build-asan/ and runs the CPU and GPU tests
# there; any sanitizer report, a leak included, fails its test. Settings: tests/sanitizers.env,
# leak suppressions (dependencies only, each with its reason): tests/lsan.supp. Run by
# scripts/test.sh (and so by CI) after the plain suite, unless TERRAVT_SANITIZED=0. To run
# ctest in build-asan by hand, export the same settings first.
#
# Build: -O1 -g1, not RelWithDebInfo's -O2 -g: cheaper to compile and ASan's usual level; line
# tables are all the stacks need to name file and line. No fuzzers (build/ has their own clang
# ASan build).
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
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" \
  -DTERRAVT_SANITIZE=ON -DTERRAVT_BUILD_FUZZERS=OFF >/dev/null
cmake --build build-asan -j"$(nproc)"
built=$(date +%s)
rc=0
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 1200 -L 'cpu|gpu' || rc=$?
echo "sanitized build $((built - start)) s, tests $(($(date +%s) - built)) s"
exit $rc
