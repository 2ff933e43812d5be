// vk::Context on lavapipe (or any Vulkan device): validation really reports what it should
// (parameter errors, synchronisation hazards, memory freed under a bound buffer).
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

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

}  // namespace
}  // namespace voxfield::test
