// The validated Vulkan context of the library tests (vulkan_env.hpp).
#include "vulkan_env.hpp"

#include <gtest/gtest.h>

namespace voxfield::test {
namespace {

class VulkanEnvironment : public ::testing::Environment {
  public:
    vk::Context& context() {
        if (!context_) {
            context_ =
                std::make_unique<vk::Context>(vk::ContextOptions{"", failing_validation_log()});
        }
        return *context_;
    }
    // After the last test: the context's destruction is validated too.
    void TearDown() override { context_.reset(); }

  private:
    std::unique_ptr<vk::Context> context_;
};

VulkanEnvironment* const environment =
    static_cast<VulkanEnvironment*>(::testing::AddGlobalTestEnvironment(new VulkanEnvironment));

}  // namespace

std::shared_ptr<vk::ValidationLog> failing_validation_log() {
    return std::make_shared<vk::ValidationLog>(
        [](const std::string& message) { ADD_FAILURE() << "Vulkan validation: " << message; });
}

vk::Context& validated_vulkan() {
    return environment->context();
}

HostGate::HostGate(vk::Context& ctx, std::uint32_t count)
    : device(ctx.device()), cmd(count), fence(count) {
    VkEventCreateInfo ei{};
    ei.sType = VK_STRUCTURE_TYPE_EVENT_CREATE_INFO;
    vk::check(vkCreateEvent(device, &ei, nullptr, &event), "vkCreateEvent", "host gate");
    VkCommandPoolCreateInfo pi{};
    pi.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pi.queueFamilyIndex = ctx.queue_family();
    vk::check(vkCreateCommandPool(device, &pi, nullptr, &pool), "vkCreateCommandPool", "host gate");
    VkCommandBufferAllocateInfo ai{};
    ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = count;
    vk::check(vkAllocateCommandBuffers(device, &ai, cmd.data()), "vkAllocateCommandBuffers",
              "host gate");
    for (VkFence& f : fence) {
        VkFenceCreateInfo fi{};
        fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
        vk::check(vkCreateFence(device, &fi, nullptr, &f), "vkCreateFence", "host gate");
    }
}

HostGate::~HostGate() {
    for (VkFence f : fence) {
        vkDestroyFence(device, f, nullptr);
    }
    vkFreeCommandBuffers(device, pool, static_cast<std::uint32_t>(cmd.size()), cmd.data());
    vkDestroyCommandPool(device, pool, nullptr);
    vkDestroyEvent(device, event, nullptr);
}

void HostGate::record_wait(VkCommandBuffer c, VkPipelineStageFlags stages) const {
    vkCmdWaitEvents(c, 1, &event, VK_PIPELINE_STAGE_HOST_BIT, stages, 0, nullptr, 0, nullptr, 0,
                    nullptr);
}

void HostGate::open() const {
    vk::check(vkSetEvent(device, event), "vkSetEvent", "host gate");
}

}  // namespace voxfield::test
