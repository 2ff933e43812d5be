// The Vulkan instance, with the Khronos validation layer and synchronisation validation when
// asked for, its messages collected in a ValidationLog (context.hpp).
#include "instance.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>

namespace voxfield::vk {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

// "error [validation] VUID-...: text" (the layer's id name and message).
VKAPI_ATTR VkBool32 VKAPI_CALL on_validation_message(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT type,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
    std::string m =
        (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ? "error" : "warning";
    m += (type & VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT)    ? " [validation] "
         : (type & VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT) ? " [performance] "
                                                                    : " [general] ";
    if (data->pMessageIdName != nullptr) {
        m += std::string(data->pMessageIdName) + ": ";
    }
    m += data->pMessage != nullptr ? data->pMessage : "";
    static_cast<ValidationLog*>(user)->add(m);
    return VK_FALSE;  // the call goes on, as it would without the layer
}

VkDebugUtilsMessengerCreateInfoEXT messenger_info(ValidationLog* log) {
    VkDebugUtilsMessengerCreateInfoEXT m{};
    m.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
    m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                        VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    m.pfnUserCallback = on_validation_message;
    m.pUserData = log;
    return m;
}

}  // namespace

// An instance with `extensions` (none: headless compute only).
Instance create_instance(std::shared_ptr<ValidationLog> validation,
                         const std::vector<std::string>& extensions) {
    // lavapipe prints a non-conformance warning on stderr unless this is set; the library
    // must not print, so silence it (never overriding a value the user chose).
    ::setenv("MESA_VK_IGNORE_CONFORMANCE_WARNING", "1", 0);
    VkApplicationInfo app{};
    app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
    app.pApplicationName = "voxfield";
    app.applicationVersion = 1;
    app.pEngineName = "voxfield";
    app.apiVersion = VK_API_VERSION_1_1;
    std::vector<const char*> names;
    for (const std::string& e : extensions) {
        names.push_back(e.c_str());
    }
    VkInstanceCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
    info.pApplicationInfo = &app;
    info.enabledExtensionCount = static_cast<std::uint32_t>(names.size());
    info.ppEnabledExtensionNames = names.data();
    return Instance(info, std::move(validation),
                    extensions.empty() ? "headless instance"
                                       : "instance with the window system's surface extensions");
}

void ValidationLog::add(const std::string& message) {
    Callback callback;
    {
        const std::lock_guard<std::mutex> lock(mutex_);
        messages_.push_back(message);
        callback = on_message_;
    }
    if (callback) {
        callback(message);
    }
}

std::vector<std::string> ValidationLog::messages() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return messages_;
}

std::size_t ValidationLog::count() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return messages_.size();
}

void ValidationLog::clear() {
    const std::lock_guard<std::mutex> lock(mutex_);
    messages_.clear();
}

bool validation_layer_available() {
    std::uint32_t n = 0;
    if (vkEnumerateInstanceLayerProperties(&n, nullptr) != VK_SUCCESS) {
        return false;
    }
    std::vector<VkLayerProperties> layers(n);
    if (vkEnumerateInstanceLayerProperties(&n, layers.data()) != VK_SUCCESS) {
        return false;
    }
    return std::any_of(layers.begin(), layers.end(), [](const VkLayerProperties& l) {
        return std::strcmp(l.layerName, kValidationLayer) == 0;
    });
}

Instance::Instance(const VkInstanceCreateInfo& base, std::shared_ptr<ValidationLog> validation,
                   const std::string& what)
    : log_(std::move(validation)) {
    VkInstanceCreateInfo info = base;
    std::vector<const char*> layers(base.ppEnabledLayerNames,
                                    base.ppEnabledLayerNames + base.enabledLayerCount);
    std::vector<const char*> extensions(base.ppEnabledExtensionNames,
                                        base.ppEnabledExtensionNames + base.enabledExtensionCount);
    // Synchronisation validation on top of the layer's default checks.
    const VkValidationFeatureEnableEXT enables[] = {
        VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
    VkValidationFeaturesEXT features{};
    features.sType = VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT;
    features.enabledValidationFeatureCount = 1;
    features.pEnabledValidationFeatures = enables;
    // Reports what vkCreateInstance and vkDestroyInstance themselves find.
    VkDebugUtilsMessengerCreateInfoEXT creation = messenger_info(log_.get());
    if (log_) {
        if (!validation_layer_available()) {
            throw VkError(
                "vkCreateInstance", VK_ERROR_LAYER_NOT_PRESENT,
                std::string(kValidationLayer) +
                    " is not installed (Debian: apt-get install vulkan-validationlayers)");
        }
        layers.push_back(kValidationLayer);
        extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
        extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
        features.pNext = base.pNext;
        creation.pNext = &features;
        info.pNext = &creation;
        info.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
        info.ppEnabledLayerNames = layers.data();
        info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
        info.ppEnabledExtensionNames = extensions.data();
    }
    const VkResult r = vkCreateInstance(&info, nullptr, &instance_);
    if (r == VK_ERROR_INCOMPATIBLE_DRIVER) {
        throw VkError("vkCreateInstance", r,
                      "no Vulkan 1.1 driver is installed (install mesa-vulkan-drivers for "
                      "lavapipe, or a GPU driver; see /usr/share/vulkan/icd.d)");
    }
    check(r, "vkCreateInstance", what);
    if (log_) {
        auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
        const VkDebugUtilsMessengerCreateInfoEXT lifetime = messenger_info(log_.get());
        const VkResult m = create == nullptr ? VK_ERROR_EXTENSION_NOT_PRESENT
                                             : create(instance_, &lifetime, nullptr, &messenger_);
        if (m != VK_SUCCESS) {
            reset();
            check(m, "vkCreateDebugUtilsMessengerEXT", what);
        }
    }
}

Instance::Instance(Instance&& o) noexcept
    : instance_(std::exchange(o.instance_, VK_NULL_HANDLE)),
      messenger_(std::exchange(o.messenger_, VK_NULL_HANDLE)),
      log_(std::move(o.log_)) {}

Instance& Instance::operator=(Instance&& o) noexcept {
    if (this != &o) {
        reset();
        instance_ = std::exchange(o.instance_, VK_NULL_HANDLE);
        messenger_ = std::exchange(o.messenger_, VK_NULL_HANDLE);
        log_ = std::move(o.log_);
    }
    return *this;
}

void Instance::reset() {
    if (messenger_ != VK_NULL_HANDLE) {
        auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
            vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
        if (destroy != nullptr) {
            destroy(instance_, messenger_, nullptr);
        }
        messenger_ = VK_NULL_HANDLE;
    }
    if (instance_ != VK_NULL_HANDLE) {
        vkDestroyInstance(instance_, nullptr);
        instance_ = VK_NULL_HANDLE;
    }
}

}  // namespace voxfield::vk
