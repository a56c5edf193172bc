// Loading terravt's private Vulkan function table (gpu/vk_functions.h).
#include "gpu/vk_functions.h"

#include <string>

namespace tvt::vk {

Result<Functions> Functions::load(PFN_vkGetInstanceProcAddr get_instance_proc_addr, VkInstance instance,
                                  VkDevice device) {
  if (get_instance_proc_addr == nullptr)
    return Error{ErrorKind::invalid_argument, "get_instance_proc_addr: null; terravt looks every Vulkan function up through it"};
  const auto missing = [](const char* name) {
    return Error{ErrorKind::unsupported_device,
                 std::string("the Vulkan implementation does not provide ") + name +
                     " (terravt needs Vulkan 1.3 core functions)"};
  };
  Functions f;
#define TVT_VK_LOAD_INSTANCE(name)                                                                \
  f.vk##name = reinterpret_cast<PFN_vk##name>(get_instance_proc_addr(instance, "vk" #name)); \
  if (f.vk##name == nullptr) return missing("vk" #name);
  TVT_VK_INSTANCE_FUNCTIONS(TVT_VK_LOAD_INSTANCE)
#undef TVT_VK_LOAD_INSTANCE
#define TVT_VK_LOAD_DEVICE(name)                                                            \
  f.vk##name = reinterpret_cast<PFN_vk##name>(f.vkGetDeviceProcAddr(device, "vk" #name)); \
  if (f.vk##name == nullptr) return missing("vk" #name);
  TVT_VK_DEVICE_FUNCTIONS(TVT_VK_LOAD_DEVICE)
#undef TVT_VK_LOAD_DEVICE
  return f;
}

}  // namespace tvt::vk
