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

}  // namespace voxfield::test
