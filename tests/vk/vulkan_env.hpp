#pragma once
// The Vulkan context of the library tests, with validation on (VK_LAYER_KHRONOS_validation,
// synchronisation validation included): every message fails the test that is running, and
// the global test environment destroys the context after the last test, failing the run on
// any message its destruction gives (objects still alive, work still in flight).
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "voxfield/vk/context.hpp"

namespace voxfield::test {

// Created on first use (inside a test, so that a missing device fails that test).
vk::Context& validated_vulkan();

// The validated context, or nullptr when this machine has no Vulkan device.
inline vk::Context* vulkan_or_null() {
    try {
        return &validated_vulkan();
    } catch (const vk::DeviceSelectionError&) {
        return nullptr;
    }
}

// Declares `ctx`, the validated context, or skips the test when there is no Vulkan device.
#define REQUIRE_VULKAN(ctx)                 \
    vk::Context* ctx = vulkan_or_null();    \
    if (ctx == nullptr) {                   \
        GTEST_SKIP() << "no Vulkan device"; \
    }

// A log whose every message fails the running test (for further contexts of a test).
std::shared_ptr<vk::ValidationLog> failing_validation_log();

// Work held in flight by the host: an event that command buffers wait for
// (record_wait) until open() sets it, `count` primary command buffers and as many unsignalled
// fences for their submissions. Destroyed in order after the caller waited for them.
struct HostGate {
    HostGate(vk::Context& ctx, std::uint32_t count);
    ~HostGate();
    HostGate(const HostGate&) = delete;
    HostGate& operator=(const HostGate&) = delete;
    // Records, into cmd, a wait for the event before `stages`.
    void record_wait(VkCommandBuffer cmd, VkPipelineStageFlags stages) const;
    void open() const;

    VkDevice device;
    VkEvent event = VK_NULL_HANDLE;
    VkCommandPool pool = VK_NULL_HANDLE;
    std::vector<VkCommandBuffer> cmd;
    std::vector<VkFence> fence;
};

}  // namespace voxfield::test
