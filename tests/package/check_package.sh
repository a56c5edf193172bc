#!/usr/bin/env bash
# Installs terravt from a build tree into a temporary prefix and checks the package as an engine
# sees it: only public headers, none pulling a private dependency; libterravt exports only
# terravt:: symbols, carries its SONAME and imports no Vulkan function; libterravt.a links a
# client on its own (COMPONENTS static); find_package(terravt CONFIG) and pkg-config both
# build a client that runs. Usage: check_package.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
source "$src/tests/package/install_prefix.sh"
tvt_install_prefix "$build"

# Headers: C++ in include/terravt/*.h, GLSL in terravt/vt.glsl and terravt/glsl/; each C++
# #include is a standard header, Vulkan, or terravt/.
headers=$(cd "$prefix/include" && find . -type f | sort)
echo "installed headers:" $headers
if find "$prefix/include" -type f ! -path "$prefix/include/terravt/*.h" ! -path "$prefix/include/terravt/vt.glsl" \
     ! -path "$prefix/include/terravt/glsl/*" | grep -q .; then
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
for b in 5 6 7; do echo "$refl" | grep -q "binding $b," || { echo "FAIL: binding $b not in the shader:"; echo "$refl"; exit 1; }; done
# Without the binding macros the include says what to define.
sed '/TERRAVT_VT_BINDING/d' "$work/client.frag" > "$work/nomacros.frag"
if out=$(glslangValidator -V -I"$prefix/include" "$work/nomacros.frag" -o /dev/null 2>&1); then
  echo "FAIL: vt.glsl compiled without its binding macros"; exit 1
fi
echo "$out" | grep -q "define TERRAVT_VT_BINDING_INFO" || { echo "FAIL: no clear error: $out"; exit 1; }

lib=$(find "$prefix" -name 'libterravt.so.*.*.*' | head -n 1)
[ -n "$lib" ] || { echo "FAIL: no versioned libterravt.so installed"; exit 1; }
soname=$(objdump -p "$lib" | awk '/SONAME/ {print $2}')
case "$soname" in libterravt.so.[0-9]*) ;; *) echo "FAIL: SONAME is '$soname'"; exit 1 ;; esac
# Exports: terravt:: functions only (hidden visibility everywhere else), plus the vtable and
# typeinfo of the exported interface a client derives from (terravt::PageProducer). The
# standard library's own templates keep default visibility and come out as weak
# (vague-linkage) symbols; those are the C++ ABI's, not terravt's.
leaked=$(nm -D --defined-only -C "$lib" | awk '$2 ~ /[TWBDRVu]/' |
         awk '!($2 ~ /[WVu]/ && $0 ~ /std::/)' | cut -d' ' -f3- |
         grep -vE '^((vtable|typeinfo|typeinfo name) for )?terravt::' | grep -vE '^(_init|_fini|__bss_start|_edata|_end)$' || true)
if [ -n "$leaked" ]; then echo "FAIL: libterravt exports non-API symbols:"; echo "$leaked" | head -20; exit 1; fi

# Vulkan through the client's vkGetInstanceProcAddr only: libterravt imports no Vulkan function
# and does not link the loader (an engine that loads Vulkan its own way gets no second loader).
vk_imports=$(nm -D --undefined-only "$lib" | awk '{print $NF}' | grep -E '^vk' || true)
if [ -n "$vk_imports" ]; then echo "FAIL: libterravt calls the Vulkan loader directly:"; echo "$vk_imports" | head; exit 1; fi
if objdump -p "$lib" | grep -E 'NEEDED +libvulkan' >/dev/null; then
  echo "FAIL: libterravt links libvulkan"; exit 1
fi

# find_package(terravt CONFIG)
tvt_build_client "$src/tests/package" "$work/consumer"
"$work/consumer/consumer"

# find_package(terravt CONFIG COMPONENTS static): the same client from libterravt.a alone.
[ -f "$(dirname "$lib")/libterravt.a" ] || { echo "FAIL: no libterravt.a installed"; exit 1; }
tvt_build_client "$src/tests/package" "$work/consumer_static" -DTVT_STATIC=ON
if objdump -p "$work/consumer_static/consumer" | grep -E 'NEEDED +libterravt' >/dev/null; then
  echo "FAIL: the static client still needs libterravt.so"; exit 1
fi
"$work/consumer_static/consumer"
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
echo "package ok: $soname"
