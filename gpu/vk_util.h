// Internal helpers of the Vulkan layer (gpu/): failed Vulkan calls as errors, VkResult names,
// zeroed info structs and image aspects. Not part of the public API.
#pragma once
#include <vulkan/vulkan.h>

#include <string_view>

#include "vt/result.h"

namespace tvt::vk {

// The Error of a failed Vulkan call (`call`: the call's source text, of which the function
// name is kept): kind device_lost for VK_ERROR_DEVICE_LOST, out_of_memory for the out-of-
// memory results, vulkan otherwise; vk_result set. Vulkan failures are never fatal: the
// Context latches the first one (Context::ok(), Context::status()).
Error vulkan_error(VkResult result, std::string_view call);
// context.ok(expr, "expr"): false (and the failure latched on `context`) when expr failed.
#define TVT_VK_OK(context, expr) (context).ok((expr), #expr)

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
