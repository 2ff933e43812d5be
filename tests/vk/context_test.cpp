// vk::Context on lavapipe (or any Vulkan device): validation really reports what it should
// (parameter errors, synchronisation hazards), a submission whose wait fails is retired,
// never destroyed while the GPU may still run it, and whatever is retired lives until the
// fence of the submissions before it signals.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <utility>

#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

bool any_contains(const std::vector<std::string>& messages, const std::string& text) {
    for (const std::string& m : messages) {
        if (m.find(text) != std::string::npos) {
            return true;
        }
    }
    return false;
}

TEST(Validation, IsOffUnlessAskedFor) {
    const vk::Context plain;
    EXPECT_EQ(plain.validation(), nullptr);
    EXPECT_NE(validated_vulkan().validation(), nullptr);
}

TEST(Validation, ReportsAnInvalidParameter) {
    auto log = std::make_shared<vk::ValidationLog>();
    const vk::Context ctx(vk::ContextOptions{"", log});
    // fenceCount must be greater than 0 (the driver does nothing with an empty list).
    vkResetFences(ctx.device(), 0, nullptr);
    EXPECT_TRUE(any_contains(log->messages(), "VUID-vkResetFences-fenceCount-arraylength"))
        << log->count() << " messages";
}

TEST(Validation, ReportsASynchronisationHazard) {
    // Two writes to one buffer with no barrier between them: only synchronisation validation
    // sees this.
    auto log = std::make_shared<vk::ValidationLog>();
    vk::Context ctx(vk::ContextOptions{"", log});
    const vk::Buffer b = ctx.make_buffer(4096, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                         vk::MemoryIntent::device_local, "hazard");
    ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            vkCmdFillBuffer(cmd, b.get(), 0, VK_WHOLE_SIZE, 1);
            vkCmdFillBuffer(cmd, b.get(), 0, VK_WHOLE_SIZE, 2);
        },
        "hazard");
    EXPECT_TRUE(any_contains(log->messages(), "SYNC-HAZARD-WRITE-AFTER-WRITE"))
        << log->count() << " messages";
}

TEST(Validation, MovingABufferOverAnotherFreesNoMemoryStillBound) {
    // The layer's best-practices checks (on for this instance through its environment
    // variable) report memory freed while a buffer is still bound to it; assigning over a
    // buffer must destroy the old buffer before its memory.
    ::setenv("VK_LAYER_ENABLES", "VK_VALIDATION_FEATURE_ENABLE_BEST_PRACTICES_EXT", 1);
    auto log = std::make_shared<vk::ValidationLog>();
    vk::Context ctx(vk::ContextOptions{"", log});
    ::unsetenv("VK_LAYER_ENABLES");
    vk::Buffer a = ctx.make_buffer(4096, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                   vk::MemoryIntent::device_local, "a");
    a = ctx.make_buffer(8192, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, vk::MemoryIntent::device_local,
                        "b");
    EXPECT_EQ(a.size(), 8192u);
    EXPECT_FALSE(any_contains(log->messages(), "still has a reference to mem obj"))
        << log->messages().back();
}

TEST(Context, AFailedWaitRetiresTheSubmission) {
    // A wait that times out while the GPU still runs the work: the command buffer and fence
    // are retired (freed once the fence signals), not destroyed in use, which validation
    // would report (VUID-vkDestroyFence-fence-01120, VUID-vkFreeCommandBuffers-...-00047).
    vk::Context& ctx = validated_vulkan();
    const VkDeviceSize size = VkDeviceSize{256} << 20;
    const vk::Buffer b = ctx.make_buffer(size, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                         vk::MemoryIntent::device_local, "long fill");
    const auto fill = [&](VkCommandBuffer cmd) {
        for (int i = 0; i < 8; ++i) {
            if (i > 0) {
                VkMemoryBarrier m{};
                m.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
                m.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                m.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &m, 0, nullptr, 0,
                                     nullptr);
            }
            vkCmdFillBuffer(cmd, b.get(), 0, VK_WHOLE_SIZE, static_cast<std::uint32_t>(i));
        }
    };
    bool timed_out = false;
    for (int attempt = 0; attempt < 5 && !timed_out; ++attempt) {
        try {
            ctx.submit_and_wait(fill, "long fill", std::chrono::nanoseconds(0));
        } catch (const vk::VkError& e) {
            EXPECT_EQ(e.result(), VK_TIMEOUT) << e.what();
            timed_out = true;
        }
    }
    ASSERT_TRUE(timed_out) << "2 GiB of fills finished before a zero-timeout wait, 5 times";
    // The next submission runs after it (one queue, in order); then nothing is left.
    ctx.submit_and_wait([&](VkCommandBuffer cmd) { vkCmdFillBuffer(cmd, b.get(), 0, 4, 9); },
                        "after the timeout");
    EXPECT_EQ(ctx.retired_in_flight(), 0u);
}

TEST(Context, RetiredResourcesAreFreedOnlyAfterTheirFence) {
    // A submission that waits for the host (an event) keeps what was retired meanwhile alive,
    // whatever is checked, until its fence signals; with nothing in flight retiring frees at
    // once.
    vk::Context& ctx = validated_vulkan();
    struct Probe {
        bool* freed;
        explicit Probe(bool* f) : freed(f) {}
        Probe(Probe&& o) noexcept : freed(std::exchange(o.freed, nullptr)) {}
        ~Probe() {
            if (freed != nullptr) {
                *freed = true;
            }
        }
    };
    ctx.wait_frames_in_flight();
    bool at_once = false;
    ctx.retire(Probe(&at_once));
    EXPECT_TRUE(at_once);

    HostGate gate(ctx, 1);
    const VkCommandBuffer cmd = gate.cmd[0];
    const vk::Buffer target = ctx.make_buffer(16, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                              vk::MemoryIntent::device_local, "after the event");
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    ASSERT_EQ(vkBeginCommandBuffer(cmd, &bi), VK_SUCCESS);
    gate.record_wait(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT);
    vkCmdFillBuffer(cmd, target.get(), 0, VK_WHOLE_SIZE, 7);
    ASSERT_EQ(vkEndCommandBuffer(cmd), VK_SUCCESS);
    const VkFence fence = gate.fence[0];
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd;
    ctx.submit(si, fence, "waits for the host");

    bool freed = false;
    ctx.retire(Probe(&freed));
    for (int i = 0; i < 3; ++i) {
        EXPECT_TRUE(ctx.busy());
        EXPECT_EQ(ctx.retired_in_flight(), 1u);
        EXPECT_FALSE(freed) << "freed while its submission still runs";
    }
    gate.open();
    ctx.wait(fence, "the event's submission");
    EXPECT_TRUE(freed);
    EXPECT_EQ(ctx.retired_in_flight(), 0u);
    EXPECT_FALSE(ctx.busy());
}

}  // namespace
}  // namespace voxfield::test
