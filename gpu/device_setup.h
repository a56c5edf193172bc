// The device terravt's own tools and tests run on: an instance (with the validation layer and
// a debug-utils messenger when asked), a physical device chosen by name or index or ranked
// discrete > integrated > other (lavapipe on GPU-less machines), and a logical device with one
// GRAPHICS+COMPUTE queue and every feature terravt::enable_device_features() switches on.
// It is the "client" of terravt inside the project: Context::create() makes one and adopts its
// handles exactly as an engine's device is adopted. The only code that calls the Vulkan
// loader's exported functions: it is built apart (target terravt_device_setup), never into
// libterravt.
//
// Reads no environment variable: the CLI and the tests turn TERRAVT_DEVICE and
// TERRAVT_VALIDATION into ContextOptions.
// Thread-safety: messages()/clear_messages() may be called from any thread (the messenger
// callback runs on any thread); the rest from one.
#pragma once
#include <vulkan/vulkan.h>

#include <memory>
#include <string>
#include <vector>

#include "gpu/context.h"
#include "terravt/device.h"
#include "vt/result.h"

namespace tvt::vk {

class OwnedDevice final : public DeviceOwner {
 public:
  static Result<std::unique_ptr<OwnedDevice>> create(const ContextOptions& options);
  // Waits for the device to finish, then destroys the device, messenger and instance.
  ~OwnedDevice() override;
  OwnedDevice(const OwnedDevice&) = delete;
  OwnedDevice& operator=(const OwnedDevice&) = delete;

  // The handles to adopt (enabled_features points into this object).
  terravt::DeviceHandles handles() const override;
  bool validation() const override { return messenger_ != VK_NULL_HANDLE; }
  // Every validation (and other debug-utils warning/error) message since creation or since
  // the last clear_messages().
  std::vector<std::string> messages() const override;
  void clear_messages() override;

  struct Messages;  // the messenger's sink (implementation detail)

 private:
  OwnedDevice();
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  // The chain the device was created with: features_ -> v12_ -> v13_.
  VkPhysicalDeviceFeatures2 features_{};
  VkPhysicalDeviceVulkan12Features v12_{};
  VkPhysicalDeviceVulkan13Features v13_{};
  std::unique_ptr<Messages> messages_;
};

}  // namespace tvt::vk
