#!/usr/bin/env bash
# Installs terravt from a build tree into a temporary prefix and checks the package as an engine
# sees it: only public headers, none pulling a private dependency; libterravt exports only
# terravt:: symbols and carries its SONAME; find_package(terravt CONFIG) and pkg-config both
# build a client that runs. Usage: check_package.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" >/dev/null

# Headers: include/terravt/*.h only; each #include is a standard header, Vulkan, or terravt/.
headers=$(cd "$prefix/include" && find . -type f | sort)
echo "installed headers:" $headers
if find "$prefix/include" -type f ! -path "$prefix/include/terravt/*.h" | grep -q .; then
  echo "FAIL: something other than include/terravt/*.h was installed"; exit 1
fi
bad=$(grep -rhE '^[[:space:]]*#[[:space:]]*include' "$prefix/include" |
      grep -vE '#[[:space:]]*include[[:space:]]*(<[a-z_]+>|<vulkan/vulkan\.h>|"terravt/[a-z_]+\.h")' || true)
if [ -n "$bad" ]; then echo "FAIL: a public header includes something private:"; echo "$bad"; exit 1; fi

lib=$(find "$prefix" -name 'libterravt.so.*.*.*' | head -n 1)
[ -n "$lib" ] || { echo "FAIL: no versioned libterravt.so installed"; exit 1; }
soname=$(objdump -p "$lib" | awk '/SONAME/ {print $2}')
case "$soname" in libterravt.so.[0-9]*) ;; *) echo "FAIL: SONAME is '$soname'"; exit 1 ;; esac
# Exports: terravt:: functions only (hidden visibility everywhere else). The standard library's
# own templates keep default visibility and come out as weak (vague-linkage) symbols; those are
# the C++ ABI's, not terravt's.
leaked=$(nm -D --defined-only -C "$lib" | awk '$2 ~ /[TWBDRVu]/' |
         awk '!($2 ~ /[WVu]/ && $0 ~ /std::/)' | cut -d' ' -f3- |
         grep -vE '^terravt::' | grep -vE '^(_init|_fini|__bss_start|_edata|_end)$' || true)
if [ -n "$leaked" ]; then echo "FAIL: libterravt exports non-API symbols:"; echo "$leaked" | head -20; exit 1; fi

# find_package(terravt CONFIG)
cmake -S "$src/tests/package" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$work/consumer" >/dev/null
"$work/consumer/consumer"

# pkg-config
export PKG_CONFIG_PATH=$(dirname "$(find "$prefix" -name terravt.pc)")
c++ -std=c++20 "$src/tests/package/consumer.cpp" -o "$work/consumer_pc" $(pkg-config --cflags --libs terravt)
LD_LIBRARY_PATH=$(dirname "$lib") "$work/consumer_pc"
echo "package ok: $soname"
