// Vulkan errors: the call, its VkResult name and our context (context.hpp).
#include "voxfield/vk/context.hpp"

namespace voxfield::vk {

VkError::VkError(const std::string& call, VkResult result, const std::string& context)
    : std::runtime_error(call + " failed with " + result_name(result) +
                         (context.empty() ? std::string() : " (" + context + ")")),
      result_(result) {}

const char* result_name(VkResult r) {
    switch (r) {
#define VF_CASE(c) \
    case c:        \
        return #c;
        VF_CASE(VK_SUCCESS)
        VF_CASE(VK_NOT_READY)
        VF_CASE(VK_TIMEOUT)
        VF_CASE(VK_EVENT_SET)
        VF_CASE(VK_EVENT_RESET)
        VF_CASE(VK_INCOMPLETE)
        VF_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
        VF_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
        VF_CASE(VK_ERROR_INITIALIZATION_FAILED)
        VF_CASE(VK_ERROR_DEVICE_LOST)
        VF_CASE(VK_ERROR_MEMORY_MAP_FAILED)
        VF_CASE(VK_ERROR_LAYER_NOT_PRESENT)
        VF_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
        VF_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
        VF_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
        VF_CASE(VK_ERROR_TOO_MANY_OBJECTS)
        VF_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
        VF_CASE(VK_ERROR_FRAGMENTED_POOL)
        VF_CASE(VK_ERROR_UNKNOWN)
        VF_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
        VF_CASE(VK_ERROR_INVALID_EXTERNAL_HANDLE)
        VF_CASE(VK_ERROR_FRAGMENTATION)
        VF_CASE(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
#undef VF_CASE
        default:
            return "VkResult(unknown)";
    }
}

void check(VkResult r, const char* call, const std::string& context) {
    if (r != VK_SUCCESS) {
        throw VkError(call, r, context);
    }
}

}  // namespace voxfield::vk
