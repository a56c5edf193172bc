// Internal helpers of the Vulkan layer (gpu/): the fatal check for calls that must not fail,
// VkResult names, zeroed info structs and image aspects. Not part of the public API.
#pragma once
#include <vulkan/vulkan.h>

namespace tvt::vk {

// Fatal check for Vulkan calls that must not fail (two levels of errors: this for what only a
// broken driver or a bug causes, Result<T> for what a user can cause).
void check_result(VkResult result, const char* file, int line, const char* expr);
#define TVT_VK_CHECK(expr) ::tvt::vk::check_result((expr), __FILE__, __LINE__, #expr)

// "VK_ERROR_DEVICE_LOST" etc.; "VkResult (unnamed)" for codes not listed.
const char* result_name(VkResult result);

// A zeroed Vulkan info struct with its sType set.
template <class T>
T init(VkStructureType type) {
  T v{};
  v.sType = type;
  return v;
}

// The aspects of a format: depth and/or stencil, else colour.
VkImageAspectFlags aspect_of(VkFormat format);

}  // namespace tvt::vk
