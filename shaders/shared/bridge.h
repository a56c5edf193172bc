// One definition of every struct, constant and integer routine shared by GLSL and C++
// GLSL includes this with GL_GOOGLE_include_directive and must enable
// GL_EXT_shader_explicit_arithmetic_types_int64 first; C++ gets the same names in tvt::gpu.
#ifndef TVT_SHARED_BRIDGE_H
#define TVT_SHARED_BRIDGE_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
namespace tvt::gpu {
using uint = std::uint32_t;
using std::int64_t;
using std::uint64_t;
using vec2 = glm::vec2;
using vec4 = glm::vec4;
using mat4 = glm::mat4;
using ivec2 = glm::ivec2;
using ivec4 = glm::ivec4;
using uvec2 = glm::uvec2;
using uvec4 = glm::uvec4;
}  // namespace tvt::gpu
#define TVT_BEGIN namespace tvt::gpu {
#define TVT_END }
#define TVT_FN inline
#define TVT_CONST inline constexpr
#else
#define TVT_BEGIN
#define TVT_END
#define TVT_FN
#define TVT_CONST const
#endif

#endif
