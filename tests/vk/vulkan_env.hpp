#pragma once
// The Vulkan context of the library tests, with validation on (VK_LAYER_KHRONOS_validation,
// synchronisation validation included): every message fails the test that is running, and
// the global test environment destroys the context after the last test, failing the run on
// any message its destruction gives (objects still alive, work still in flight).
#include <memory>

#include "voxfield/vk/context.hpp"

namespace voxfield::test {

// Created on first use (inside a test, so that a missing device fails that test).
vk::Context& validated_vulkan();

// A log whose every message fails the running test (for further contexts of a test).
std::shared_ptr<vk::ValidationLog> failing_validation_log();

}  // namespace voxfield::test
