#!/usr/bin/env bash
# Installs terravt from a build tree into a temporary prefix and checks the package as an engine
# sees it: only public headers, none pulling a private dependency; libterravt and
# libterravt_compose export only terravt:: symbols, carry their SONAMEs and import no Vulkan
# function; a client that streams baked stores (libterravt alone) links no OpenImageIO, OpenCV
# or other compose-side library; libterravt.a and libterravt_compose.a link a client on their
# own (COMPONENTS static [compose]); find_package(terravt CONFIG) and pkg-config both build
# clients that run. Usage: check_package.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
source "$src/tests/package/install_prefix.sh"
tvt_install_prefix "$build"

# Headers: C++ in include/terravt/*.h, GLSL in terravt/vt.glsl and terravt/glsl/; each C++
# #include is a standard header, Vulkan, or terravt/.
headers=$(cd "$prefix/include" && find . -type f | sort)
echo "installed headers:" $headers
# (No `| grep -q` under pipefail: grep quitting early kills the writer with SIGPIPE and the
# pipeline fails at random; here-strings and command substitutions instead.)
if [ -n "$(find "$prefix/include" -type f ! -path "$prefix/include/terravt/*.h" ! -path "$prefix/include/terravt/vt.glsl" \
     ! -path "$prefix/include/terravt/glsl/*")" ]; then
  echo "FAIL: something other than terravt's headers was installed"; exit 1
fi
bad=$(cat "$prefix"/include/terravt/*.h | grep -E '^[[:space:]]*#[[:space:]]*include' |
      grep -vE '#[[:space:]]*include[[:space:]]*(<[a-z_]+>|<vulkan/vulkan\.h>|"terravt/[a-z_]+\.h")' || true)
if [ -n "$bad" ]; then echo "FAIL: a public header includes something private:"; echo "$bad"; exit 1; fi

# The GLSL contract compiles against the installed include alone, at bindings the client picks.
cat > "$work/client.frag" <<'GLSL'
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define TERRAVT_VT_SET 2
#define TERRAVT_VT_BINDING_INFO 5
#define TERRAVT_VT_BINDING_TABLE 6
#define TERRAVT_VT_BINDING_CACHE 7
#include "terravt/vt.glsl"
layout(location = 0) flat in ivec2 in_texel;
layout(location = 1) in vec2 in_frac;
layout(location = 0) out vec4 out_colour;
layout(location = 1) out uvec2 out_request;
void main() {
  const vec2 dx = dFdx(in_frac), dy = dFdy(in_frac);
  out_colour = terravt_sample(in_texel, in_frac, dx, dy);
  out_request = terravt_feedback(in_texel, dx, dy);
}
GLSL
glslangValidator -V --target-env vulkan1.3 -I"$prefix/include" "$work/client.frag" -o "$work/client.spv" >/dev/null ||
  { glslangValidator -V --target-env vulkan1.3 -I"$prefix/include" "$work/client.frag" -o "$work/client.spv"; exit 1; }
# The bindings are the client's: bindings 5, 6, 7 in the SPIR-V (glslang's reflection lists
# them; spirv-dis is not needed).
refl=$(glslangValidator -V --target-env vulkan1.3 -q -I"$prefix/include" "$work/client.frag" -o /dev/null)
for b in 5 6 7; do grep -q "binding $b," <<<"$refl" || { echo "FAIL: binding $b not in the shader:"; echo "$refl"; exit 1; }; done
# Without the binding macros the include says what to define.
sed '/TERRAVT_VT_BINDING/d' "$work/client.frag" > "$work/nomacros.frag"
if out=$(glslangValidator -V -I"$prefix/include" "$work/nomacros.frag" -o /dev/null 2>&1); then
  echo "FAIL: vt.glsl compiled without its binding macros"; exit 1
fi
grep -q "define TERRAVT_VT_BINDING_INFO" <<<"$out" || { echo "FAIL: no clear error: $out"; exit 1; }

check_shared_lib() {  # check_shared_lib NAME: the installed libNAME.so.X.Y.Z; sets $lib
  lib=$(find "$prefix" -name "lib$1.so.*.*.*" | head -n 1)
  [ -n "$lib" ] || { echo "FAIL: no versioned lib$1.so installed"; exit 1; }
  soname=$(objdump -p "$lib" | awk '/SONAME/ {print $2}')
  case "$soname" in lib$1.so.[0-9]*) ;; *) echo "FAIL: SONAME of lib$1 is '$soname'"; exit 1 ;; esac
  # Exports: terravt:: functions only (hidden visibility everywhere else), plus the vtable and
  # typeinfo of the exported interface a client derives from (terravt::PageProducer). The
  # standard library's own templates keep default visibility and come out as weak
  # (vague-linkage) symbols; those are the C++ ABI's, not terravt's.
  leaked=$(nm -D --defined-only -C "$lib" | awk '$2 ~ /[TWBDRVu]/' |
           awk '!($2 ~ /[WVu]/ && $0 ~ /std::/)' | cut -d' ' -f3- |
           grep -vE '^((vtable|typeinfo|typeinfo name) for )?terravt::' | grep -vE '^(_init|_fini|__bss_start|_edata|_end)$' || true)
  leaked=$(printf '%s\n' "$leaked" "$(nm -D --defined-only -C "$lib" | grep -E 'terravt::detail::' || true)" | grep . || true)
  if [ -n "$leaked" ]; then echo "FAIL: lib$1 exports non-API symbols:"; echo "$leaked" | head -20; exit 1; fi
  # Vulkan through the client's vkGetInstanceProcAddr only: no Vulkan function imported, no
  # loader linked (an engine that loads Vulkan its own way gets no second loader).
  vk_imports=$(nm -D --undefined-only "$lib" | awk '{print $NF}' | grep -E '^vk' || true)
  if [ -n "$vk_imports" ]; then echo "FAIL: lib$1 calls the Vulkan loader directly:"; echo "$vk_imports" | head; exit 1; fi
  if objdump -p "$lib" | grep -E 'NEEDED +libvulkan' >/dev/null; then
    echo "FAIL: lib$1 links libvulkan"; exit 1
  fi
}
# What the compose component brings and a store-streaming client must not load.
compose_deps='libOpenImageIO|libopencv|libavcodec|libgdal|libgst|libpng|libjpeg|libtiff|libOpenEXR'
check_no_compose_deps() {  # check_no_compose_deps BINARY: neither it nor what it loads needs them
  local found
  found=$( { objdump -p "$1" | awk '/NEEDED/ {print $2}'; ldd "$1" | awk '{print $1}'; } | grep -E "$compose_deps" || true)
  if [ -n "$found" ]; then echo "FAIL: $1 loads compose-side libraries:"; echo "$found" | sort -u | head; exit 1; fi
}
run_compose_client() {  # run_compose_client BINARY: runs it and checks it reached the compose component
  local out
  out=$("$1") || { echo "$out"; echo "FAIL: $1 failed"; exit 1; }
  case "$out" in *"compose component linked"*) ;; *) echo "$out"; echo "FAIL: $1 did not call the compose component"; exit 1 ;; esac
}
check_shared_lib terravt_compose
compose_lib=$lib
objdump -p "$compose_lib" | grep -E 'NEEDED +libterravt\.so' >/dev/null ||
  { echo "FAIL: libterravt_compose does not build on libterravt.so"; exit 1; }
check_shared_lib terravt
check_no_compose_deps "$lib"
echo "libterravt loads $(ldd "$lib" | wc -l) libraries; libterravt_compose $(ldd "$compose_lib" | wc -l)"

# find_package(terravt CONFIG): a client that streams stores links libterravt alone...
tvt_build_client "$src/tests/package" "$work/consumer"
check_no_compose_deps "$work/consumer/consumer"
"$work/consumer/consumer"
# ... and with COMPONENTS compose the compose component too.
tvt_build_client "$src/tests/package" "$work/consumer_compose" -DTVT_COMPOSE=ON
objdump -p "$work/consumer_compose/consumer" | grep -E 'NEEDED +libterravt_compose' >/dev/null ||
  { echo "FAIL: the compose client does not link libterravt_compose"; exit 1; }
run_compose_client "$work/consumer_compose/consumer"

# find_package(terravt CONFIG COMPONENTS static): the same client from libterravt.a alone.
[ -f "$(dirname "$lib")/libterravt.a" ] || { echo "FAIL: no libterravt.a installed"; exit 1; }
tvt_build_client "$src/tests/package" "$work/consumer_static" -DTVT_STATIC=ON
if objdump -p "$work/consumer_static/consumer" | grep -E 'NEEDED +libterravt' >/dev/null; then
  echo "FAIL: the static client still needs libterravt.so"; exit 1
fi
check_no_compose_deps "$work/consumer_static/consumer"
"$work/consumer_static/consumer"
[ -f "$(dirname "$lib")/libterravt_compose.a" ] || { echo "FAIL: no libterravt_compose.a installed"; exit 1; }
tvt_build_client "$src/tests/package" "$work/consumer_compose_static" -DTVT_STATIC=ON -DTVT_COMPOSE=ON
if objdump -p "$work/consumer_compose_static/consumer" | grep -E 'NEEDED +libterravt' >/dev/null; then
  echo "FAIL: the static compose client still needs a libterravt shared library"; exit 1
fi
run_compose_client "$work/consumer_compose_static/consumer"
# static first, then static and compose in a later call of the same project: the archive of
# compose still comes (the first call made terravt::terravt_static already).
mkdir -p "$work/two_calls"
cat > "$work/two_calls/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.25)
project(two_calls LANGUAGES CXX)
find_package(terravt CONFIG REQUIRED COMPONENTS static)
find_package(terravt CONFIG REQUIRED COMPONENTS static compose)
if(NOT TARGET terravt::compose_static OR NOT TARGET terravt::compose)
  message(FATAL_ERROR "terravt::compose_static missing after the second find_package")
endif()
CMAKE
cmake -S "$work/two_calls" -B "$work/two_calls/build" -DCMAKE_PREFIX_PATH="$prefix" >"$work/two_calls.log" 2>&1 ||
  { cat "$work/two_calls.log"; echo "FAIL: find_package(static) then (static compose)"; exit 1; }
# A component that does not exist is refused by find_package.
mkdir -p "$work/bad_component"
cat > "$work/bad_component/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.25)
project(bad LANGUAGES CXX)
find_package(terravt CONFIG REQUIRED COMPONENTS no_such_component)
CMAKE
if cmake -S "$work/bad_component" -B "$work/bad_component/build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null 2>&1; then
  echo "FAIL: find_package accepted an unknown component"; exit 1
fi

# pkg-config
export PKG_CONFIG_PATH=$(dirname "$(find "$prefix" -name terravt.pc)")
c++ -std=c++20 "$src/tests/package/consumer.cpp" -o "$work/consumer_pc" $(pkg-config --cflags --libs terravt)
LD_LIBRARY_PATH=$(dirname "$lib") "$work/consumer_pc"
c++ -std=c++20 -DTVT_WITH_COMPOSE "$src/tests/package/consumer.cpp" -o "$work/consumer_compose_pc" \
  $(pkg-config --cflags --libs terravt_compose)
LD_LIBRARY_PATH=$(dirname "$lib") run_compose_client "$work/consumer_compose_pc"
echo "package ok: $soname"
