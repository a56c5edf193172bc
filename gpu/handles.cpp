// Move-only RAII handles of gpu/context.h: a moved-from object owns nothing; reset()
// frees in reverse creation order. Move construction is move assignment into the empty
// (default-initialised) object, so each class lists its members once per direction.
#include <utility>

#include "gpu/context.h"

namespace tvt::vk {

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    fn_ = std::exchange(o.fn_, nullptr);
    alloc_ = std::exchange(o.alloc_, nullptr);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
  }
  return *this;
}

Buffer::~Buffer() { reset(); }

void Buffer::reset() {
  if (device_) {
    if (buffer_) fn_->vkDestroyBuffer(device_, buffer_, alloc_);
    if (memory_) fn_->vkFreeMemory(device_, memory_, alloc_);  // unmaps implicitly
  }
  device_ = VK_NULL_HANDLE;
  fn_ = nullptr;
  alloc_ = nullptr;
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  size_ = 0;
  mapped_ = nullptr;
}

Image::Image(Image&& o) noexcept { *this = std::move(o); }

Image& Image::operator=(Image&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    fn_ = std::exchange(o.fn_, nullptr);
    alloc_ = std::exchange(o.alloc_, nullptr);
    image_ = std::exchange(o.image_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    format_ = std::exchange(o.format_, VK_FORMAT_UNDEFINED);
    width_ = std::exchange(o.width_, 0);
    height_ = std::exchange(o.height_, 0);
    layers_ = std::exchange(o.layers_, 0);
    mip_levels_ = std::exchange(o.mip_levels_, 0);
  }
  return *this;
}

Image::~Image() { reset(); }

void Image::reset() {
  if (device_) {
    if (view_) fn_->vkDestroyImageView(device_, view_, alloc_);
    if (image_) fn_->vkDestroyImage(device_, image_, alloc_);
    if (memory_) fn_->vkFreeMemory(device_, memory_, alloc_);
  }
  device_ = VK_NULL_HANDLE;
  fn_ = nullptr;
  alloc_ = nullptr;
  image_ = VK_NULL_HANDLE;
  view_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  format_ = VK_FORMAT_UNDEFINED;
  width_ = height_ = layers_ = mip_levels_ = 0;
}

PipelineHandles::PipelineHandles(PipelineHandles&& o) noexcept { *this = std::move(o); }

PipelineHandles& PipelineHandles::operator=(PipelineHandles&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    fn_ = std::exchange(o.fn_, nullptr);
    alloc_ = std::exchange(o.alloc_, nullptr);
    pipeline_ = std::exchange(o.pipeline_, VK_NULL_HANDLE);
    layout_ = std::exchange(o.layout_, VK_NULL_HANDLE);
    set_layout_ = std::exchange(o.set_layout_, VK_NULL_HANDLE);
  }
  return *this;
}

PipelineHandles::~PipelineHandles() { reset(); }

void PipelineHandles::reset() {
  if (device_) {
    if (pipeline_) fn_->vkDestroyPipeline(device_, pipeline_, alloc_);
    if (layout_) fn_->vkDestroyPipelineLayout(device_, layout_, alloc_);
    if (set_layout_) fn_->vkDestroyDescriptorSetLayout(device_, set_layout_, alloc_);
  }
  device_ = VK_NULL_HANDLE;
  fn_ = nullptr;
  alloc_ = nullptr;
  pipeline_ = VK_NULL_HANDLE;
  layout_ = VK_NULL_HANDLE;
  set_layout_ = VK_NULL_HANDLE;
}

DescriptorSet::DescriptorSet(DescriptorSet&& o) noexcept { *this = std::move(o); }

DescriptorSet& DescriptorSet::operator=(DescriptorSet&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    fn_ = std::exchange(o.fn_, nullptr);
    alloc_ = std::exchange(o.alloc_, nullptr);
    pool_ = std::exchange(o.pool_, VK_NULL_HANDLE);
    set_ = std::exchange(o.set_, VK_NULL_HANDLE);
  }
  return *this;
}

DescriptorSet::~DescriptorSet() { reset(); }

void DescriptorSet::reset() {
  // Destroying the pool frees the set (the pool has no FREE_DESCRIPTOR_SET_BIT).
  if (device_ && pool_) fn_->vkDestroyDescriptorPool(device_, pool_, alloc_);
  device_ = VK_NULL_HANDLE;
  fn_ = nullptr;
  alloc_ = nullptr;
  pool_ = VK_NULL_HANDLE;
  set_ = VK_NULL_HANDLE;
}

}  // namespace tvt::vk
