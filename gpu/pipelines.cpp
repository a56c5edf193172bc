// Pipelines and descriptor sets (gpu/pipelines.h), made by the Context.
#include <algorithm>
#include <vector>

#include "gpu/context.h"

namespace tvt::vk {

namespace {

// A stage's specialization constants as Vulkan takes them (32 bits each); info() is null
// when there are none. Not copyable: the info points into the object's own arrays.
class Specialization {
 public:
  explicit Specialization(std::span<const SpecConstant> constants) {
    for (const SpecConstant& c : constants) {
      entries_.push_back({c.id, uint32_t(values_.size() * sizeof(uint32_t)), sizeof(uint32_t)});
      values_.push_back(c.value);
    }
    info_ = {uint32_t(entries_.size()), entries_.data(), values_.size() * sizeof(uint32_t), values_.data()};
  }
  Specialization(const Specialization&) = delete;
  Specialization& operator=(const Specialization&) = delete;
  const VkSpecializationInfo* info() const { return entries_.empty() ? nullptr : &info_; }

 private:
  std::vector<VkSpecializationMapEntry> entries_;
  std::vector<uint32_t> values_;
  VkSpecializationInfo info_{};
};

}  // namespace

ComputePipeline Context::create_compute_pipeline(std::span<const uint32_t> spirv,
                                                 std::span<const ComputeBinding> bindings,
                                                 uint32_t push_constant_bytes,
                                                 std::span<const SpecConstant> constants) {
  TVT_CHECK(!spirv.empty());
  TVT_CHECK(push_constant_bytes % 4 == 0);
  if (!status()) return {};  // nothing more is made after a failed call
  ComputePipeline p;
  p.device_ = device_;
  p.fn_ = &fn_;
  p.alloc_ = alloc_;
  p.bindings_.assign(bindings.begin(), bindings.end());

  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const ComputeBinding& b : bindings) {
    lb.push_back({b.binding, b.type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  }
  auto dci = init<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  dci.bindingCount = uint32_t(lb.size());
  dci.pBindings = lb.data();
  if (!TVT_VK_OK(*this, fn_.vkCreateDescriptorSetLayout(device_, &dci, alloc_, &p.set_layout_))) return {};

  const VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_constant_bytes};
  auto plci = init<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &p.set_layout_;
  plci.pushConstantRangeCount = push_constant_bytes ? 1u : 0u;
  plci.pPushConstantRanges = &range;
  if (!TVT_VK_OK(*this, fn_.vkCreatePipelineLayout(device_, &plci, alloc_, &p.layout_))) return {};

  const VkShaderModule module = create_shader_module(spirv);
  if (module == VK_NULL_HANDLE) return {};

  auto cpci = init<VkComputePipelineCreateInfo>(VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO);
  cpci.stage = init<VkPipelineShaderStageCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO);
  cpci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  cpci.stage.module = module;
  cpci.stage.pName = "main";
  const Specialization spec(constants);
  cpci.stage.pSpecializationInfo = spec.info();
  cpci.layout = p.layout_;
  const VkResult r = fn_.vkCreateComputePipelines(device_, VK_NULL_HANDLE, 1, &cpci, alloc_, &p.pipeline_);
  fn_.vkDestroyShaderModule(device_, module, alloc_);
  if (!TVT_VK_OK(*this, r)) return {};
  return p;
}

DescriptorSet Context::allocate_descriptor_set(const ComputePipeline& pipeline) {
  if (pipeline.set_layout_ == VK_NULL_HANDLE) return {};  // the pipeline's creation failed (latched)
  std::vector<VkDescriptorType> types;
  for (const ComputeBinding& b : pipeline.bindings_) types.push_back(b.type);
  return allocate_set(pipeline.set_layout_, types);
}

DescriptorSet Context::allocate_descriptor_set(const GraphicsPipeline& pipeline) {
  if (pipeline.set_layout_ == VK_NULL_HANDLE) return {};  // the pipeline's creation failed (latched)
  return allocate_set(pipeline.set_layout_, pipeline.types_);
}

DescriptorSet Context::allocate_set(VkDescriptorSetLayout layout, std::span<const VkDescriptorType> types) {
  if (!status()) return {};  // nothing more is made after a failed call
  DescriptorSet s;
  s.device_ = device_;
  s.fn_ = &fn_;
  s.alloc_ = alloc_;
  std::vector<VkDescriptorPoolSize> sizes;
  for (const VkDescriptorType type : types) {
    auto it = std::find_if(sizes.begin(), sizes.end(), [&](const VkDescriptorPoolSize& ps) { return ps.type == type; });
    if (it == sizes.end()) {
      sizes.push_back({type, 1});
    } else {
      ++it->descriptorCount;
    }
  }
  if (sizes.empty()) sizes.push_back({VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1});  // keep the pool create valid
  auto pci = init<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  pci.maxSets = 1;
  pci.poolSizeCount = uint32_t(sizes.size());
  pci.pPoolSizes = sizes.data();
  if (!TVT_VK_OK(*this, fn_.vkCreateDescriptorPool(device_, &pci, alloc_, &s.pool_))) return {};
  auto ai = init<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
  ai.descriptorPool = s.pool_;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &layout;
  if (!TVT_VK_OK(*this, fn_.vkAllocateDescriptorSets(device_, &ai, &s.set_))) return {};
  return s;
}

VkShaderModule Context::create_shader_module(std::span<const uint32_t> spirv) {
  TVT_CHECK(!spirv.empty());
  auto smci = init<VkShaderModuleCreateInfo>(VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO);
  smci.codeSize = spirv.size_bytes();
  smci.pCode = spirv.data();
  VkShaderModule module = VK_NULL_HANDLE;
  if (!TVT_VK_OK(*this, fn_.vkCreateShaderModule(device_, &smci, alloc_, &module))) return VK_NULL_HANDLE;
  return module;
}

GraphicsPipeline Context::create_graphics_pipeline(const GraphicsPipelineDesc& desc) {
  if (!features_.dynamic_rendering) {
    ok(VK_ERROR_FEATURE_NOT_PRESENT, "vkCreateGraphicsPipelines (dynamicRendering is not enabled)");
    return {};
  }
  TVT_CHECK(!desc.vertex_spirv.empty() && !desc.fragment_spirv.empty());
  TVT_CHECK(desc.push_constant_bytes % 4 == 0);
  TVT_CHECK(!desc.color_formats.empty() || desc.depth_format != VK_FORMAT_UNDEFINED);
  if (!status()) return {};  // nothing more is made after a failed call
  GraphicsPipeline p;
  p.device_ = device_;
  p.fn_ = &fn_;
  p.alloc_ = alloc_;
  p.push_stages_ = desc.push_constant_bytes ? desc.push_constant_stages : 0;

  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const GraphicsBinding& b : desc.bindings) {
    lb.push_back({b.binding, b.type, 1, b.stages, nullptr});
    p.types_.push_back(b.type);
  }
  auto dci = init<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  dci.bindingCount = uint32_t(lb.size());
  dci.pBindings = lb.data();
  if (!TVT_VK_OK(*this, fn_.vkCreateDescriptorSetLayout(device_, &dci, alloc_, &p.set_layout_))) return {};

  const VkPushConstantRange range{desc.push_constant_stages, 0, desc.push_constant_bytes};
  auto plci = init<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &p.set_layout_;
  plci.pushConstantRangeCount = desc.push_constant_bytes ? 1u : 0u;
  plci.pPushConstantRanges = &range;
  if (!TVT_VK_OK(*this, fn_.vkCreatePipelineLayout(device_, &plci, alloc_, &p.layout_))) return {};

  const VkShaderModule vs = create_shader_module(desc.vertex_spirv);
  const VkShaderModule fs = vs == VK_NULL_HANDLE ? VK_NULL_HANDLE : create_shader_module(desc.fragment_spirv);
  if (fs == VK_NULL_HANDLE) {
    if (vs != VK_NULL_HANDLE) fn_.vkDestroyShaderModule(device_, vs, alloc_);
    return {};
  }
  // Fragment specialization constants: constant_id i = desc.fragment_constants[i].
  std::vector<SpecConstant> fragment_constants;
  for (uint32_t i = 0; i < desc.fragment_constants.size(); ++i) fragment_constants.push_back({i, desc.fragment_constants[i]});
  const Specialization spec(fragment_constants);
  VkPipelineShaderStageCreateInfo stages[2];
  for (int i = 0; i < 2; ++i) {
    stages[i] = init<VkPipelineShaderStageCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO);
    stages[i].stage = i == 0 ? VK_SHADER_STAGE_VERTEX_BIT : VK_SHADER_STAGE_FRAGMENT_BIT;
    stages[i].module = i == 0 ? vs : fs;
    stages[i].pName = "main";
    if (i == 1) stages[i].pSpecializationInfo = spec.info();
  }

  auto vi = init<VkPipelineVertexInputStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO);
  vi.vertexBindingDescriptionCount = uint32_t(desc.vertex_bindings.size());
  vi.pVertexBindingDescriptions = desc.vertex_bindings.data();
  vi.vertexAttributeDescriptionCount = uint32_t(desc.vertex_attributes.size());
  vi.pVertexAttributeDescriptions = desc.vertex_attributes.data();
  auto ia = init<VkPipelineInputAssemblyStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO);
  ia.topology = desc.topology;
  auto vp = init<VkPipelineViewportStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO);
  vp.viewportCount = 1;
  vp.scissorCount = 1;
  auto rs = init<VkPipelineRasterizationStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO);
  rs.polygonMode = VK_POLYGON_MODE_FILL;
  rs.cullMode = desc.cull_mode;
  rs.frontFace = desc.front_face;
  rs.lineWidth = 1.0f;
  auto ms = init<VkPipelineMultisampleStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO);
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  auto ds = init<VkPipelineDepthStencilStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO);
  const bool depth = desc.depth_format != VK_FORMAT_UNDEFINED;
  ds.depthTestEnable = depth ? VK_TRUE : VK_FALSE;
  ds.depthWriteEnable = depth && desc.depth_write ? VK_TRUE : VK_FALSE;
  ds.depthCompareOp = desc.depth_compare;
  std::vector<VkPipelineColorBlendAttachmentState> blend(desc.color_formats.size());
  for (auto& b : blend) {
    b.blendEnable = VK_FALSE;
    b.colorWriteMask =
        VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
  }
  auto cb = init<VkPipelineColorBlendStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO);
  cb.attachmentCount = uint32_t(blend.size());
  cb.pAttachments = blend.data();
  const VkDynamicState dynamic[] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  auto dyn = init<VkPipelineDynamicStateCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO);
  dyn.dynamicStateCount = 2;
  dyn.pDynamicStates = dynamic;
  auto rendering = init<VkPipelineRenderingCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO);
  rendering.colorAttachmentCount = uint32_t(desc.color_formats.size());
  rendering.pColorAttachmentFormats = desc.color_formats.data();
  rendering.depthAttachmentFormat = desc.depth_format;

  auto gpci = init<VkGraphicsPipelineCreateInfo>(VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO);
  gpci.pNext = &rendering;
  gpci.stageCount = 2;
  gpci.pStages = stages;
  gpci.pVertexInputState = &vi;
  gpci.pInputAssemblyState = &ia;
  gpci.pViewportState = &vp;
  gpci.pRasterizationState = &rs;
  gpci.pMultisampleState = &ms;
  gpci.pDepthStencilState = &ds;
  gpci.pColorBlendState = &cb;
  gpci.pDynamicState = &dyn;
  gpci.layout = p.layout_;
  const VkResult r = fn_.vkCreateGraphicsPipelines(device_, VK_NULL_HANDLE, 1, &gpci, alloc_, &p.pipeline_);
  fn_.vkDestroyShaderModule(device_, vs, alloc_);
  fn_.vkDestroyShaderModule(device_, fs, alloc_);
  if (!TVT_VK_OK(*this, r)) return {};
  return p;
}

void DescriptorSet::write_buffer(uint32_t binding, VkDescriptorType type, const Buffer& buffer) {
  write_buffer(binding, type, buffer.handle(), 0);
}

void DescriptorSet::write_buffer(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset) {
  // An empty set or buffer: its creation failed, latched on the Context; nothing to write.
  if (set_ == VK_NULL_HANDLE || buffer == VK_NULL_HANDLE) return;
  TVT_CHECK(type == VK_DESCRIPTOR_TYPE_STORAGE_BUFFER || type == VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  const VkDescriptorBufferInfo info{buffer, offset, VK_WHOLE_SIZE};
  auto w = init<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  w.pBufferInfo = &info;
  fn_->vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_image(uint32_t binding, VkDescriptorType type, const VkDescriptorImageInfo& info) {
  if (set_ == VK_NULL_HANDLE || info.imageView == VK_NULL_HANDLE) return;  // creation failed (latched)
  auto w = init<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  w.dstSet = set_;
  w.dstBinding = binding;
  w.descriptorCount = 1;
  w.descriptorType = type;
  w.pImageInfo = &info;
  fn_->vkUpdateDescriptorSets(device_, 1, &w, 0, nullptr);
}

void DescriptorSet::write_storage_image(uint32_t binding, const Image& image) {
  write_image(binding, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, {VK_NULL_HANDLE, image.view(), VK_IMAGE_LAYOUT_GENERAL});
}

void DescriptorSet::write_sampled_image(uint32_t binding, const Image& image, VkSampler sampler, VkImageLayout layout) {
  if (sampler == VK_NULL_HANDLE) return;  // its creation failed (latched on the Context)
  write_image(binding, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, {sampler, image.view(), layout});
}

}  // namespace tvt::vk
