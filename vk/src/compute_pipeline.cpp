// The shared steps of the compute passes (compute_pipeline.hpp).
#include "compute_pipeline.hpp"

#include <array>

namespace voxfield::vk {

VkDescriptorSetLayoutBinding compute_binding(std::uint32_t binding, VkDescriptorType type) {
    VkDescriptorSetLayoutBinding x{};
    x.binding = binding;
    x.descriptorType = type;
    x.descriptorCount = 1;
    x.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    return x;
}

Owned<VkDescriptorSetLayout> make_set_layout(
    VkDevice dev, const std::vector<VkDescriptorSetLayoutBinding>& bindings,
    const std::string& what) {
    VkDescriptorSetLayoutCreateInfo sl{};
    sl.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    sl.bindingCount = static_cast<std::uint32_t>(bindings.size());
    sl.pBindings = bindings.data();
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    check(vkCreateDescriptorSetLayout(dev, &sl, nullptr, &set_layout),
          "vkCreateDescriptorSetLayout", what);
    return Owned<VkDescriptorSetLayout>(dev, set_layout, vkDestroyDescriptorSetLayout);
}

Owned<VkPipelineLayout> make_pipeline_layout(VkDevice dev, VkDescriptorSetLayout set_layout,
                                             std::uint32_t push_bytes, const std::string& what) {
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes};
    VkPipelineLayoutCreateInfo pl{};
    pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &set_layout;
    pl.pushConstantRangeCount = 1;
    pl.pPushConstantRanges = &range;
    VkPipelineLayout pipeline_layout = VK_NULL_HANDLE;
    check(vkCreatePipelineLayout(dev, &pl, nullptr, &pipeline_layout), "vkCreatePipelineLayout",
          what);
    return Owned<VkPipelineLayout>(dev, pipeline_layout, vkDestroyPipelineLayout);
}

Owned<VkShaderModule> make_shader(VkDevice dev, const std::uint32_t* code, std::size_t bytes,
                                  const std::string& what) {
    VkShaderModuleCreateInfo sm{};
    sm.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    sm.codeSize = bytes;
    sm.pCode = code;
    VkShaderModule shader = VK_NULL_HANDLE;
    check(vkCreateShaderModule(dev, &sm, nullptr, &shader), "vkCreateShaderModule", what);
    return Owned<VkShaderModule>(dev, shader, vkDestroyShaderModule);
}

Owned<VkDescriptorPool> make_set_pool(VkDevice dev, std::uint32_t buffers,
                                      const std::string& what) {
    const std::array<VkDescriptorPoolSize, 2> sizes = {
        VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1},
        VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, buffers}};
    VkDescriptorPoolCreateInfo dp{};
    dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    dp.maxSets = 1;
    dp.poolSizeCount = static_cast<std::uint32_t>(sizes.size());
    dp.pPoolSizes = sizes.data();
    VkDescriptorPool pool = VK_NULL_HANDLE;
    check(vkCreateDescriptorPool(dev, &dp, nullptr, &pool), "vkCreateDescriptorPool", what);
    return Owned<VkDescriptorPool>(dev, pool, vkDestroyDescriptorPool);
}

VkDescriptorSet allocate_set(VkDevice dev, VkDescriptorPool pool, VkDescriptorSetLayout layout,
                             const std::string& what) {
    VkDescriptorSetAllocateInfo da{};
    da.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    da.descriptorPool = pool;
    da.descriptorSetCount = 1;
    da.pSetLayouts = &layout;
    VkDescriptorSet set = VK_NULL_HANDLE;
    check(vkAllocateDescriptorSets(dev, &da, &set), "vkAllocateDescriptorSets", what);
    return set;
}

Owned<VkQueryPool> make_timestamp_pool(VkDevice dev, std::uint32_t count, const std::string& what) {
    VkQueryPoolCreateInfo qp{};
    qp.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
    qp.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qp.queryCount = count;
    VkQueryPool q = VK_NULL_HANDLE;
    check(vkCreateQueryPool(dev, &qp, nullptr, &q), "vkCreateQueryPool", what);
    return Owned<VkQueryPool>(dev, q, vkDestroyQueryPool);
}

Owned<VkPipeline> make_compute_pipeline(VkDevice dev, VkShaderModule shader,
                                        VkPipelineLayout layout, const VkSpecializationInfo& spec,
                                        const std::string& what) {
    VkComputePipelineCreateInfo cp{};
    cp.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    cp.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cp.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cp.stage.module = shader;
    cp.stage.pName = "main";
    cp.stage.pSpecializationInfo = &spec;
    cp.layout = layout;
    VkPipeline pipeline = VK_NULL_HANDLE;
    check(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &cp, nullptr, &pipeline),
          "vkCreateComputePipelines", what);
    return Owned<VkPipeline>(dev, pipeline, vkDestroyPipeline);
}

VkWriteDescriptorSet descriptor_write(VkDescriptorSet set, std::uint32_t binding,
                                      VkDescriptorType type) {
    VkWriteDescriptorSet w{};
    w.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    w.dstSet = set;
    w.dstBinding = binding;
    w.descriptorCount = 1;
    w.descriptorType = type;
    return w;
}

VkImageMemoryBarrier color_barrier(VkImage image, VkAccessFlags src, VkAccessFlags dst,
                                   VkImageLayout from, VkImageLayout to) {
    VkImageMemoryBarrier b{};
    b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    b.srcAccessMask = src;
    b.dstAccessMask = dst;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    return b;
}

double timestamp_pair_ms(Context& ctx, VkQueryPool pool, std::uint32_t first, bool wait,
                         const std::string& what) {
    std::array<std::uint64_t, 2> ts{};
    const VkResult r = vkGetQueryPoolResults(
        ctx.device(), pool, first, 2, sizeof ts, ts.data(), sizeof(std::uint64_t),
        wait ? VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT : VK_QUERY_RESULT_64_BIT);
    if (r == VK_NOT_READY) {
        return -1;
    }
    check(r, "vkGetQueryPoolResults", what);
    return static_cast<double>(ts[1] - ts[0]) * static_cast<double>(ctx.timestamp_period_ns()) *
           1e-6;
}

OffscreenTarget make_offscreen_target(Context& ctx, std::uint32_t width, std::uint32_t height,
                                      const std::string& what, const std::string& memory_what,
                                      const std::string& readback_what) {
    const VkDevice dev = ctx.device();
    OffscreenTarget target;
    VkImageCreateInfo ii{};
    ii.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    ii.imageType = VK_IMAGE_TYPE_2D;
    ii.format = VK_FORMAT_R32_UINT;
    ii.extent = {width, height, 1};
    ii.mipLevels = 1;
    ii.arrayLayers = 1;
    ii.samples = VK_SAMPLE_COUNT_1_BIT;
    ii.tiling = VK_IMAGE_TILING_OPTIMAL;
    ii.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    ii.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    ii.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    VkImage image = VK_NULL_HANDLE;
    check(vkCreateImage(dev, &ii, nullptr, &image), "vkCreateImage", what);
    target.image = Owned<VkImage>(dev, image, vkDestroyImage);
    VkMemoryRequirements req{};
    vkGetImageMemoryRequirements(dev, image, &req);
    target.memory = ctx.allocate(req, MemoryIntent::device_local, memory_what);
    check(vkBindImageMemory(dev, image, target.memory.get(), 0), "vkBindImageMemory", what);
    VkImageViewCreateInfo vi{};
    vi.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
    vi.image = image;
    vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vi.format = VK_FORMAT_R32_UINT;
    vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    VkImageView view = VK_NULL_HANDLE;
    check(vkCreateImageView(dev, &vi, nullptr, &view), "vkCreateImageView", what);
    target.view = Owned<VkImageView>(dev, view, vkDestroyImageView);
    target.readback =
        ctx.make_buffer(VkDeviceSize{width} * height * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        MemoryIntent::readback, readback_what);
    target.width = width;
    target.height = height;
    return target;
}

}  // namespace voxfield::vk
