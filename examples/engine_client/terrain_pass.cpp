// The engine's terrain pass (see terrain_pass.h).
#include "terrain_pass.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>

namespace engine {

namespace {

// std140 layout of `Frame` in shaders/common.glsl.
struct FrameConstants {
  glm::mat4 clip_from_relative;
  glm::vec4 camera;   // camera texel minus anchor (xy), camera height (z), metres per texel (w)
  glm::ivec4 anchor;  // anchor texel (xy), texels per quad (z)
  glm::uvec4 feedback;  // divisor, this frame's pixel of the block (y, z), feedback row length
};
static_assert(sizeof(FrameConstants) == 112);

// The feedback word layout of terravt/vt.glsl (terravt/glsl/shared/feedback_types.h):
// word0 = page_x | mip << 27, word1 = page_y (bits 27..31 reserved); mip 31: no request.
constexpr uint32_t kCoordMask = (1u << 27) - 1u;
constexpr uint32_t kEmptyMip = 31;

VkShaderModule load_shader(VkDevice device, const std::string& path, std::string& error) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.empty() || bytes.size() % 4 != 0) {
    error = "cannot read the SPIR-V file " + path;
    return VK_NULL_HANDLE;
  }
  std::vector<uint32_t> words(bytes.size() / 4);
  std::memcpy(words.data(), bytes.data(), bytes.size());
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = bytes.size();
  ci.pCode = words.data();
  VkShaderModule m = VK_NULL_HANDLE;
  vkCreateShaderModule(device, &ci, nullptr, &m);
  return m;
}

void barrier(VkCommandBuffer cmd, VkPipelineStageFlags src, VkAccessFlags src_access, VkPipelineStageFlags dst,
             VkAccessFlags dst_access) {
  VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  vkCmdPipelineBarrier(cmd, src, dst, 0, 1, &b, 0, nullptr, 0, nullptr);
}

}  // namespace

glm::dmat4 Camera::clip_from_relative(double aspect) const {
  const glm::dvec3 f{std::cos(pitch_rad) * std::cos(yaw_rad), std::cos(pitch_rad) * std::sin(yaw_rad), std::sin(pitch_rad)};
  const glm::dvec3 r{std::sin(yaw_rad), -std::cos(yaw_rad), 0.0};  // horizontal: no singularity looking down
  const glm::dvec3 u = glm::cross(r, f);
  glm::dmat4 view(1.0);  // [column][row]
  for (int c = 0; c < 3; ++c) {
    view[c][0] = r[c];
    view[c][1] = u[c];
    view[c][2] = -f[c];
  }
  const double t = 1.0 / std::tan(vertical_fov_rad * 0.5);
  glm::dmat4 p(0.0);
  p[0][0] = t / aspect;
  p[1][1] = -t;  // Vulkan: framebuffer y points down
  p[2][2] = near_m / (far_m - near_m);
  p[3][2] = near_m * far_m / (far_m - near_m);
  p[2][3] = -1.0;
  return p * view;
}

std::unique_ptr<TerrainPass> TerrainPass::create(Device& device, const TerrainPassDesc& desc, std::string& error) {
  std::unique_ptr<TerrainPass> t(new TerrainPass(device));
  t->desc_ = desc;
  const VkDevice d = device.device();
  const uint64_t vt_texels = uint64_t(1) << desc.log2_size;
  const uint64_t quads = uint64_t(desc.chunks_per_side) * desc.quads_per_chunk;
  if (quads > vt_texels) {
    error = "--chunks x --quads-per-chunk (" + std::to_string(quads) + ") exceeds the VT's " + std::to_string(vt_texels) +
            " texels per side";
    return nullptr;
  }
  t->quad_texels_ = uint32_t(vt_texels / quads);
  t->metres_per_texel_ = desc.extent_m / double(vt_texels);
  const uint32_t n = desc.feedback_divisor;
  t->fb_width_ = (desc.width + n - 1) / n;
  t->fb_height_ = (desc.height + n - 1) / n;

  // Targets and the classic render pass.
  const VkFormat colour_format = VK_FORMAT_R8G8B8A8_UNORM, depth_format = VK_FORMAT_D32_SFLOAT;
  t->colour_ = device.create_image(colour_format, desc.width, desc.height,
                                   VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
  t->depth_ = device.create_image(depth_format, desc.width, desc.height, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                                  VK_IMAGE_ASPECT_DEPTH_BIT);
  std::array<VkAttachmentDescription, 2> att{};
  att[0].format = colour_format;
  att[0].samples = VK_SAMPLE_COUNT_1_BIT;
  att[0].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  att[0].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  att[0].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  att[0].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[0].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  att[0].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  att[1] = att[0];
  att[1].format = depth_format;
  att[1].storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[1].finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
  const VkAttachmentReference colour_ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  const VkAttachmentReference depth_ref{1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub{};
  sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  sub.colorAttachmentCount = 1;
  sub.pColorAttachments = &colour_ref;
  sub.pDepthStencilAttachment = &depth_ref;
  // Both frames in flight render into one colour and depth image: each frame's writes wait for
  // the previous frame's writes and for the read-back copy (queue order does the rest).
  std::array<VkSubpassDependency, 2> deps{};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT | VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                         VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[0].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[0].dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT | VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                         VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  deps[0].dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                          VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  deps[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  VkRenderPassCreateInfo rpci{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  rpci.attachmentCount = uint32_t(att.size());
  rpci.pAttachments = att.data();
  rpci.subpassCount = 1;
  rpci.pSubpasses = &sub;
  rpci.dependencyCount = uint32_t(deps.size());
  rpci.pDependencies = deps.data();
  vkCreateRenderPass(d, &rpci, nullptr, &t->render_pass_);
  const VkImageView views[] = {t->colour_.view, t->depth_.view};
  VkFramebufferCreateInfo fci{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
  fci.renderPass = t->render_pass_;
  fci.attachmentCount = 2;
  fci.pAttachments = views;
  fci.width = desc.width;
  fci.height = desc.height;
  fci.layers = 1;
  vkCreateFramebuffer(d, &fci, nullptr, &t->framebuffer_);

  // The engine's descriptor layout: its own frame constants (0) and feedback buffer (1), and
  // terravt's description (5), page table (6) and cache (7), where the engine chose to put them.
  const VkShaderStageFlags frag = VK_SHADER_STAGE_FRAGMENT_BIT;
  const VkDescriptorSetLayoutBinding bindings[] = {
      {0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT | frag, nullptr},
      {1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, frag, nullptr},
      {5, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, frag, nullptr},
      {6, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, frag, nullptr},
      {7, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, frag, nullptr},
  };
  VkDescriptorSetLayoutCreateInfo lci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  lci.bindingCount = uint32_t(std::size(bindings));
  lci.pBindings = bindings;
  vkCreateDescriptorSetLayout(d, &lci, nullptr, &t->set_layout_);
  VkPipelineLayoutCreateInfo plci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &t->set_layout_;
  vkCreatePipelineLayout(d, &plci, nullptr, &t->pipeline_layout_);

  // Pipeline.
  const std::string dir = ENGINE_CLIENT_SHADER_DIR;
  const VkShaderModule vs = load_shader(d, dir + "/terrain.vert.spv", error);
  const VkShaderModule fs = vs ? load_shader(d, dir + "/terrain.frag.spv", error) : VK_NULL_HANDLE;
  if (!vs || !fs) {
    if (vs) vkDestroyShaderModule(d, vs, nullptr);
    return nullptr;
  }
  VkPipelineShaderStageCreateInfo stages[2]{};
  stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO, nullptr, 0, VK_SHADER_STAGE_VERTEX_BIT, vs, "main", nullptr};
  stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO, nullptr, 0, VK_SHADER_STAGE_FRAGMENT_BIT, fs, "main", nullptr};
  const VkVertexInputBindingDescription vbind[] = {{0, 4, VK_VERTEX_INPUT_RATE_VERTEX}, {1, 8, VK_VERTEX_INPUT_RATE_INSTANCE}};
  const VkVertexInputAttributeDescription vattr[] = {{0, 0, VK_FORMAT_R16G16_UINT, 0}, {1, 1, VK_FORMAT_R32G32_SINT, 0}};
  VkPipelineVertexInputStateCreateInfo vi{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  vi.vertexBindingDescriptionCount = 2;
  vi.pVertexBindingDescriptions = vbind;
  vi.vertexAttributeDescriptionCount = 2;
  vi.pVertexAttributeDescriptions = vattr;
  VkPipelineInputAssemblyStateCreateInfo ia{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  const VkViewport viewport{0, 0, float(desc.width), float(desc.height), 0, 1};
  const VkRect2D scissor{{0, 0}, {desc.width, desc.height}};
  VkPipelineViewportStateCreateInfo vp{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  vp.viewportCount = 1;
  vp.pViewports = &viewport;
  vp.scissorCount = 1;
  vp.pScissors = &scissor;
  VkPipelineRasterizationStateCreateInfo rs{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  rs.polygonMode = VK_POLYGON_MODE_FILL;
  rs.cullMode = VK_CULL_MODE_BACK_BIT;
  rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;  // triangles are counter-clockwise seen from above
  rs.lineWidth = 1.0f;
  VkPipelineMultisampleStateCreateInfo ms{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineDepthStencilStateCreateInfo ds{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  ds.depthTestEnable = VK_TRUE;
  ds.depthWriteEnable = VK_TRUE;
  ds.depthCompareOp = VK_COMPARE_OP_GREATER_OR_EQUAL;  // reverse-Z
  VkPipelineColorBlendAttachmentState blend{};
  blend.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
  VkPipelineColorBlendStateCreateInfo cb{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  cb.attachmentCount = 1;
  cb.pAttachments = &blend;
  VkGraphicsPipelineCreateInfo gci{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  gci.stageCount = 2;
  gci.pStages = stages;
  gci.pVertexInputState = &vi;
  gci.pInputAssemblyState = &ia;
  gci.pViewportState = &vp;
  gci.pRasterizationState = &rs;
  gci.pMultisampleState = &ms;
  gci.pDepthStencilState = &ds;
  gci.pColorBlendState = &cb;
  gci.layout = t->pipeline_layout_;
  gci.renderPass = t->render_pass_;
  const VkResult pr = vkCreateGraphicsPipelines(d, VK_NULL_HANDLE, 1, &gci, nullptr, &t->pipeline_);
  vkDestroyShaderModule(d, vs, nullptr);
  vkDestroyShaderModule(d, fs, nullptr);
  if (pr != VK_SUCCESS) {
    error = "vkCreateGraphicsPipelines failed (VkResult " + std::to_string(int(pr)) + ")";
    return nullptr;
  }

  // The chunk grid: (q+1)^2 vertices, two counter-clockwise triangles per quad.
  const uint32_t q = desc.quads_per_chunk, side = q + 1;
  std::vector<uint16_t> grid;
  for (uint32_t j = 0; j <= q; ++j)
    for (uint32_t i = 0; i <= q; ++i) grid.insert(grid.end(), {uint16_t(i), uint16_t(j)});
  std::vector<uint32_t> index;
  for (uint32_t j = 0; j < q; ++j)
    for (uint32_t i = 0; i < q; ++i) {
      const uint32_t a = j * side + i, b = a + 1, c = a + side + 1, e = a + side;
      index.insert(index.end(), {a, b, c, a, c, e});
    }
  t->index_count_ = uint32_t(index.size());
  // Host-visible static geometry: small, and it keeps the example free of a staging upload.
  t->vertices_ = device.create_buffer(grid.size() * 2, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
  std::memcpy(t->vertices_.mapped, grid.data(), grid.size() * 2);
  t->indices_ = device.create_buffer(index.size() * 4, VK_BUFFER_USAGE_INDEX_BUFFER_BIT, true);
  std::memcpy(t->indices_.mapped, index.data(), index.size() * 4);

  // Per frame in flight: constants, visible chunk origins, feedback; one descriptor set each.
  const uint32_t k = desc.frames_in_flight;
  const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, k},
                                        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 3 * k},
                                        {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, k}};
  VkDescriptorPoolCreateInfo dpci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpci.maxSets = k;
  dpci.poolSizeCount = uint32_t(std::size(sizes));
  dpci.pPoolSizes = sizes;
  vkCreateDescriptorPool(d, &dpci, nullptr, &t->pool_);
  const uint32_t chunks = desc.chunks_per_side * desc.chunks_per_side;
  t->slots_.resize(k);
  for (Slot& s : t->slots_) {
    s.frame = device.create_buffer(sizeof(FrameConstants), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
    s.instances = device.create_buffer(VkDeviceSize(chunks) * 8, VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, true);
    s.feedback = device.create_buffer(VkDeviceSize(t->fb_width_) * t->fb_height_ * 8,
                                      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, desc.feedback_on_host);
    VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    ai.descriptorPool = t->pool_;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &t->set_layout_;
    vkAllocateDescriptorSets(d, &ai, &s.set);
    const VkDescriptorBufferInfo frame_info{s.frame.buffer, 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo feedback_info{s.feedback.buffer, 0, VK_WHOLE_SIZE};
    const VkDescriptorBufferInfo vt_info{desc.vt.info_buffer, 0, desc.vt.info_bytes};
    const VkDescriptorBufferInfo vt_table{desc.vt.table_buffer, 0, desc.vt.table_bytes};
    const VkDescriptorImageInfo vt_cache{desc.vt.cache_sampler, desc.vt.cache_view, desc.vt.cache_layout};
    auto write = [&](uint32_t binding, VkDescriptorType type, const VkDescriptorBufferInfo* b, const VkDescriptorImageInfo* i) {
      VkWriteDescriptorSet w{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
      w.dstSet = s.set;
      w.dstBinding = binding;
      w.descriptorCount = 1;
      w.descriptorType = type;
      w.pBufferInfo = b;
      w.pImageInfo = i;
      return w;
    };
    const VkWriteDescriptorSet writes[] = {
        write(0, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, &frame_info, nullptr),
        write(1, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, &feedback_info, nullptr),
        write(5, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, &vt_info, nullptr),
        write(6, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, &vt_table, nullptr),
        write(7, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, nullptr, &vt_cache),
    };
    vkUpdateDescriptorSets(d, uint32_t(std::size(writes)), writes, 0, nullptr);
  }
  t->colour_readback_ = device.create_buffer(VkDeviceSize(desc.width) * desc.height * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  t->table_readback_ = device.create_buffer(desc.vt.table_bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  return t;
}

TerrainPass::~TerrainPass() {
  const VkDevice d = dev_.device();
  for (Slot& s : slots_) {
    dev_.destroy(s.frame);
    dev_.destroy(s.instances);
    dev_.destroy(s.feedback);
  }
  dev_.destroy(vertices_);
  dev_.destroy(indices_);
  dev_.destroy(colour_readback_);
  dev_.destroy(table_readback_);
  if (pool_) vkDestroyDescriptorPool(d, pool_, nullptr);
  if (pipeline_) vkDestroyPipeline(d, pipeline_, nullptr);
  if (pipeline_layout_) vkDestroyPipelineLayout(d, pipeline_layout_, nullptr);
  if (set_layout_) vkDestroyDescriptorSetLayout(d, set_layout_, nullptr);
  if (framebuffer_) vkDestroyFramebuffer(d, framebuffer_, nullptr);
  if (render_pass_) vkDestroyRenderPass(d, render_pass_, nullptr);
  dev_.destroy(colour_);
  dev_.destroy(depth_);
}

glm::dvec2 TerrainPass::camera_texel(const Camera& camera) const {
  return glm::dvec2(camera.position_m.x, camera.position_m.y) / metres_per_texel_;
}

void TerrainPass::record(VkCommandBuffer cmd, uint32_t slot, uint64_t frame, const Camera& camera) {
  Slot& s = slots_[slot];
  const double aspect = double(desc_.width) / double(desc_.height);
  const glm::dmat4 clip = camera.clip_from_relative(aspect);
  const glm::dvec2 ct = camera_texel(camera);
  const terravt::TexelAnchor anchor = terravt::texel_anchor(ct.x, ct.y);

  // Culling: chunk boxes (z = 0) against the six frustum planes, camera-relative, in double;
  // visible chunks front to back so early depth tests reject hidden fragments.
  const auto row = [&](int i) { return glm::dvec4(clip[0][i], clip[1][i], clip[2][i], clip[3][i]); };
  const glm::dvec4 planes[] = {row(3) + row(0), row(3) - row(0), row(3) + row(1), row(3) - row(1), row(2), row(3) - row(2)};
  const double chunk_m = double(desc_.quads_per_chunk) * quad_texels_ * metres_per_texel_;
  std::vector<std::pair<double, glm::ivec2>> visible;
  for (uint32_t cy = 0; cy < desc_.chunks_per_side; ++cy)
    for (uint32_t cx = 0; cx < desc_.chunks_per_side; ++cx) {
      const glm::dvec3 lo{cx * chunk_m - camera.position_m.x, cy * chunk_m - camera.position_m.y, -camera.position_m.z};
      const glm::dvec3 hi{lo.x + chunk_m, lo.y + chunk_m, lo.z};
      bool inside = true;
      for (const glm::dvec4& p : planes) {
        const glm::dvec3 v(p.x >= 0 ? hi.x : lo.x, p.y >= 0 ? hi.y : lo.y, p.z >= 0 ? hi.z : lo.z);
        inside = inside && glm::dot(glm::dvec3(p), v) + p.w >= 0.0;
      }
      if (!inside) continue;
      const glm::dvec3 centre = (lo + hi) * 0.5;
      const int64_t origin_x = int64_t(cx) * desc_.quads_per_chunk * quad_texels_;
      const int64_t origin_y = int64_t(cy) * desc_.quads_per_chunk * quad_texels_;
      visible.push_back({glm::length(centre), glm::ivec2(int32_t(origin_x - anchor.x), int32_t(origin_y - anchor.y))});
    }
  std::stable_sort(visible.begin(), visible.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  auto* origins = static_cast<glm::ivec2*>(s.instances.mapped);
  for (size_t i = 0; i < visible.size(); ++i) origins[i] = visible[i].second;
  drawn_ = uint32_t(visible.size());

  // Frame constants; the rotating feedback pixel walks the N x N block (every pixel once in N^2 frames).
  const uint32_t n = desc_.feedback_divisor, i = uint32_t(frame % (uint64_t(n) * n));
  FrameConstants fc{};
  fc.clip_from_relative = glm::mat4(clip);
  fc.camera = glm::vec4(anchor.fx, anchor.fy, float(camera.position_m.z), float(metres_per_texel_));
  fc.anchor = glm::ivec4(anchor.x, anchor.y, int32_t(quad_texels_), 0);
  fc.feedback = glm::uvec4(n, (i * 7u) % n, (i / n + i * 3u) % n, fb_width_);
  std::memcpy(s.frame.mapped, &fc, sizeof(fc));

  // Feedback: cleared to "no request" after the previous use of this buffer by the GPU (this
  // pass's fragment writes, and on the GPU route terravt's compaction reading it with compute).
  barrier(cmd, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT,
          VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
  vkCmdFillBuffer(cmd, s.feedback.buffer, 0, VK_WHOLE_SIZE, 0xffffffffu);
  barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
          VK_ACCESS_SHADER_WRITE_BIT);

  VkClearValue clears[2]{};
  clears[0].color = {{0.0f, 0.0f, 0.0f, 1.0f}};
  clears[1].depthStencil = {0.0f, 0};  // reverse-Z: far
  VkRenderPassBeginInfo rbi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
  rbi.renderPass = render_pass_;
  rbi.framebuffer = framebuffer_;
  rbi.renderArea = {{0, 0}, {desc_.width, desc_.height}};
  rbi.clearValueCount = 2;
  rbi.pClearValues = clears;
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  if (drawn_ > 0) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_layout_, 0, 1, &s.set, 0, nullptr);
    const VkBuffer vbs[] = {vertices_.buffer, s.instances.buffer};
    const VkDeviceSize offsets[] = {0, 0};
    vkCmdBindVertexBuffers(cmd, 0, 2, vbs, offsets);
    vkCmdBindIndexBuffer(cmd, indices_.buffer, 0, VK_INDEX_TYPE_UINT32);
    // One draw for the whole terrain: on lavapipe every draw of a pipeline that writes a
    // storage buffer flushes the binned scene.
    vkCmdDrawIndexed(cmd, index_count_, drawn_, 0, 0, 0);
  }
  vkCmdEndRenderPass(cmd);
  // The GPU route needs no barrier here: record_feedback() places its own after these writes.
  if (desc_.feedback_on_host)
    barrier(cmd, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT,
            VK_ACCESS_HOST_READ_BIT);
}

void TerrainPass::record_readback(VkCommandBuffer cmd, VkBuffer table, VkDeviceSize table_bytes) {
  // The colour image is in TRANSFER_SRC_OPTIMAL after the pass (its 0 -> external dependency).
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {desc_.width, desc_.height, 1};
  vkCmdCopyImageToBuffer(cmd, colour_.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, colour_readback_.buffer, 1, &region);
  // terravt wrote this frame's table updates with compute and transfer commands in record().
  barrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
          VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
  const VkBufferCopy copy{0, 0, std::min(table_bytes, table_readback_.size)};
  vkCmdCopyBuffer(cmd, table, table_readback_.buffer, 1, &copy);
  barrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_HOST_BIT, VK_ACCESS_HOST_READ_BIT);
}

std::vector<terravt::PageRequest> TerrainPass::read_requests(uint32_t slot) const {
  if (!desc_.feedback_on_host) return {};
  const auto* words = static_cast<const uint32_t*>(slots_[slot].feedback.mapped);
  std::map<uint64_t, uint32_t> pixels;  // (mip, y, x) -> feedback pixels
  for (size_t t = 0; t < size_t(fb_width_) * fb_height_; ++t) {
    const uint32_t w0 = words[2 * t], w1 = words[2 * t + 1];
    const uint32_t mip = w0 >> 27;
    if (mip == kEmptyMip) continue;
    ++pixels[(uint64_t(mip) << 54) | (uint64_t(w1 & kCoordMask) << 27) | (w0 & kCoordMask)];
  }
  std::vector<terravt::PageRequest> out;
  out.reserve(pixels.size());
  for (const auto& [key, count] : pixels)
    out.push_back({uint32_t(key >> 54), uint32_t(key & kCoordMask), uint32_t((key >> 27) & kCoordMask), count});
  return out;
}

std::vector<uint8_t> TerrainPass::colour_rgba() const {
  const auto* p = static_cast<const uint8_t*>(colour_readback_.mapped);
  return std::vector<uint8_t>(p, p + colour_readback_.size);
}

std::vector<uint8_t> TerrainPass::table_bytes() const {
  const auto* p = static_cast<const uint8_t*>(table_readback_.mapped);
  return std::vector<uint8_t>(p, p + table_readback_.size);
}

}  // namespace engine
