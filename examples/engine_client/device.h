// The engine's own Vulkan device: instance (with the validation layer and synchronisation
// validation when asked), a physical device, one GRAPHICS+COMPUTE queue, and a logical device
// whose feature chain terravt::enable_device_features() completed. terravt is handed these
// handles; it creates, waits on and destroys none of them. Plus the few buffer/image helpers
// the example needs.
#pragma once
#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <terravt/terravt.h>

namespace engine {

// Every validation message (and terravt log line of level warning or above) is kept here; the
// example fails at exit when any arrived.
struct Messages {
  std::mutex mutex;
  std::vector<std::string> lines;
  void add(std::string line);
  std::vector<std::string> take();
};

struct Buffer {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  void* mapped = nullptr;  // host-visible buffers only
};

struct Image {
  VkImage image = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
};

class Device {
 public:
  // Returns null with `error` set when no Vulkan 1.3 device with a GRAPHICS+COMPUTE queue and
  // terravt's required features exists, or the validation layer was asked for and is missing.
  static std::unique_ptr<Device> create(bool validation, std::string& error);
  ~Device();
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;

  // What terravt adopts. The log callback feeds messages().
  terravt::DeviceHandles handles();
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return family_; }
  std::string name() const;
  Messages& messages() { return messages_; }

  // host: HOST_VISIBLE | HOST_COHERENT (mapped), preferring HOST_CACHED for read-backs.
  Buffer create_buffer(VkDeviceSize size, VkBufferUsageFlags usage, bool host);
  void destroy(Buffer& b);
  Image create_image(VkFormat format, uint32_t width, uint32_t height, VkImageUsageFlags usage, VkImageAspectFlags aspect);
  void destroy(Image& i);

 private:
  Device() = default;
  uint32_t memory_type(uint32_t bits, VkMemoryPropertyFlags want, VkMemoryPropertyFlags prefer) const;
  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t family_ = 0;
  VkPhysicalDeviceMemoryProperties memory_{};
  // The chain the device was created with (terravt checks it): f2 -> f12 -> f13.
  VkPhysicalDeviceFeatures2 f2_{};
  VkPhysicalDeviceVulkan12Features f12_{};
  VkPhysicalDeviceVulkan13Features f13_{};
  Messages messages_;
};

}  // namespace engine
