#include "voxfield/vk/context.hpp"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>

#include "voxfield/layout.h"

namespace voxfield::vk {
namespace {

// The ray marcher's palette plus field and material slabs (voxfield/layout.h).
constexpr std::uint32_t kStorageBuffersNeeded = 2 * VF_RAYMARCH_MAX_SLABS + 1;

std::string type_name(VkPhysicalDeviceType t) {
    switch (t) {
        case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
            return "discrete-gpu";
        case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
            return "integrated-gpu";
        case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
            return "virtual-gpu";
        case VK_PHYSICAL_DEVICE_TYPE_CPU:
            return "cpu";
        default:
            return "other";
    }
}

std::string version_string(std::uint32_t v) {
    return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) +
           "." + std::to_string(VK_API_VERSION_PATCH(v));
}

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

// An instance with `extensions` (none: headless compute only).
Instance create_instance(std::shared_ptr<ValidationLog> validation,
                         const std::vector<std::string>& extensions = {}) {
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

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
    std::uint32_t n = 0;
    check(vkEnumeratePhysicalDevices(instance, &n, nullptr), "vkEnumeratePhysicalDevices");
    std::vector<VkPhysicalDevice> devices(n);
    check(vkEnumeratePhysicalDevices(instance, &n, devices.data()), "vkEnumeratePhysicalDevices");
    devices.resize(n);
    return devices;
}

// The first queue family with compute, preferring one without graphics (async compute);
// returns false when there is none.
bool compute_family(VkPhysicalDevice d, std::uint32_t& family, bool& timestamps) {
    std::uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, nullptr);
    std::vector<VkQueueFamilyProperties> families(n);
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, families.data());
    bool found = false;
    for (std::uint32_t i = 0; i < n; ++i) {
        if ((families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) == 0) {
            continue;
        }
        if (!found) {
            family = i;
            timestamps = families[i].timestampValidBits > 0;
            found = true;
        }
    }
    return found;
}

// The first queue family that does graphics (and compute, when `compute`) and presents to
// `surface`; returns why there is none ("" when found).
std::string present_family(VkPhysicalDevice d, VkSurfaceKHR surface, bool compute,
                           std::uint32_t& family, bool& timestamps) {
    std::uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, nullptr);
    std::vector<VkQueueFamilyProperties> families(n);
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, families.data());
    bool compute_graphics = false;
    for (std::uint32_t i = 0; i < n; ++i) {
        const VkQueueFlags both = (compute ? VkQueueFlags{VK_QUEUE_COMPUTE_BIT} : VkQueueFlags{0}) |
                                  VK_QUEUE_GRAPHICS_BIT;
        if ((families[i].queueFlags & both) != both) {
            continue;
        }
        compute_graphics = true;
        VkBool32 present = VK_FALSE;
        if (vkGetPhysicalDeviceSurfaceSupportKHR(d, i, surface, &present) == VK_SUCCESS &&
            present == VK_TRUE) {
            family = i;
            timestamps = families[i].timestampValidBits > 0;
            return "";
        }
    }
    const std::string needs = compute ? "compute and graphics" : "graphics";
    return compute_graphics ? "no queue family that does " + needs + " presents to the window"
                            : "has no queue family that does " + needs;
}

PhysicalDeviceInfo describe_device(VkPhysicalDevice d, std::size_t index) {
    VkPhysicalDeviceProperties p{};
    vkGetPhysicalDeviceProperties(d, &p);
    PhysicalDeviceInfo info;
    info.index = index;
    info.name = p.deviceName;
    info.type = type_name(p.deviceType);
    info.api_version = p.apiVersion;
    info.api = version_string(p.apiVersion);
    info.driver = std::to_string(p.driverVersion);
    info.max_storage_buffer_range = p.limits.maxStorageBufferRange;
    info.max_storage_buffers_per_stage = p.limits.maxPerStageDescriptorStorageBuffers;
    info.max_image_dimension_2d = p.limits.maxImageDimension2D;
    info.min_storage_buffer_offset_alignment = p.limits.minStorageBufferOffsetAlignment;
    std::uint32_t n = 0;
    vkEnumerateDeviceExtensionProperties(d, nullptr, &n, nullptr);
    std::vector<VkExtensionProperties> ext(n);
    vkEnumerateDeviceExtensionProperties(d, nullptr, &n, ext.data());
    for (std::uint32_t i = 0; i < n; ++i) {
        info.extensions.emplace_back(ext[i].extensionName);
    }
    if (p.apiVersion >= VK_API_VERSION_1_1) {
        VkPhysicalDeviceExternalMemoryHostPropertiesEXT host{};
        host.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_EXTERNAL_MEMORY_HOST_PROPERTIES_EXT;
        VkPhysicalDeviceIDProperties id{};
        id.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ID_PROPERTIES;
        if (info.has_extension(VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME)) {
            id.pNext = &host;
        }
        VkPhysicalDeviceProperties2 p2{};
        p2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2;
        p2.pNext = &id;
        vkGetPhysicalDeviceProperties2(d, &p2);
        std::memcpy(info.uuid.data(), id.deviceUUID, VK_UUID_SIZE);
        info.min_imported_host_pointer_alignment = host.minImportedHostPointerAlignment;
    }
    std::uint32_t family = 0;
    bool timestamps = false;
    if (p.apiVersion < VK_API_VERSION_1_1) {
        info.rejected = "supports only Vulkan " + info.api + " (1.1 needed)";
    } else if (!compute_family(d, family, timestamps)) {
        info.rejected = "has no compute queue";
    } else if (p.limits.maxPerStageDescriptorStorageBuffers < kStorageBuffersNeeded) {
        info.rejected = "allows " + std::to_string(p.limits.maxPerStageDescriptorStorageBuffers) +
                        " storage buffers per shader stage (the ray marcher needs " +
                        std::to_string(kStorageBuffersNeeded) + ")";
    }
    info.timestamps = timestamps && p.limits.timestampComputeAndGraphics == VK_TRUE;
    return info;
}

std::string describe(const PhysicalDeviceInfo& d) {
    return "#" + std::to_string(d.index) + " " + d.name + " (" + d.type + ")";
}

int type_rank(const std::string& type) {
    static const std::array<const char*, 5> order = {"discrete-gpu", "integrated-gpu",
                                                     "virtual-gpu", "cpu", "other"};
    for (std::size_t i = 0; i < order.size(); ++i) {
        if (type == order[i]) {
            return static_cast<int>(i);
        }
    }
    return static_cast<int>(order.size());
}

// The device `spec` asks for among `infos`: the best type that no reason rejects (`extra`
// adds a reason of its own, e.g. that a device cannot present). Throws DeviceSelectionError
// listing every device and why it was rejected.
const PhysicalDeviceInfo& choose(
    const std::vector<PhysicalDeviceInfo>& infos, const std::string& options_spec,
    const std::function<std::string(const PhysicalDeviceInfo&)>& extra) {
    std::string spec = options_spec, origin = "Vulkan device";
    if (spec.empty()) {
        if (const char* env = std::getenv("VOXFIELD_VK_DEVICE"); env != nullptr && *env != '\0') {
            spec = env;
            origin = "VOXFIELD_VK_DEVICE";
        }
    }
    const bool is_index = !spec.empty() && std::all_of(spec.begin(), spec.end(),
                                                       [](char c) { return c >= '0' && c <= '9'; });
    if (!spec.empty() && spec != "gpu" && spec != "cpu" && !is_index) {
        throw DeviceSelectionError(origin + " '" + spec +
                                   "' is not a device: use gpu, cpu or a Vulkan device index");
    }
    if (infos.empty()) {
        throw DeviceSelectionError(
            "no Vulkan device found (install mesa-vulkan-drivers for lavapipe, or a GPU driver)");
    }
    std::string reasons;
    const PhysicalDeviceInfo* best = nullptr;
    for (const auto& d : infos) {
        std::string why = d.rejected;
        if (why.empty() && is_index && std::to_string(d.index) != spec) {
            why = "not index " + spec;
        } else if (why.empty() && spec == "cpu" && d.type != "cpu") {
            why = "is a " + d.type + ", not a cpu";
        } else if (why.empty() && spec == "gpu" && d.type.find("gpu") == std::string::npos) {
            why = "is a " + d.type + ", not a gpu";
        }
        if (why.empty() && extra) {
            why = extra(d);
        }
        if (!why.empty()) {
            reasons += (reasons.empty() ? "" : "; ") + describe(d) + ": " + why;
            continue;
        }
        if (best == nullptr || type_rank(d.type) < type_rank(best->type)) {
            best = &d;
        }
    }
    if (best == nullptr) {
        throw DeviceSelectionError("no usable Vulkan device for " +
                                   (spec.empty() ? std::string("the default") : spec) + ": " +
                                   reasons);
    }
    return *best;
}

}  // namespace

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

bool PhysicalDeviceInfo::has_extension(const std::string& ext) const {
    return std::find(extensions.begin(), extensions.end(), ext) != extensions.end();
}

std::vector<PhysicalDeviceInfo> list_devices() {
    const Instance instance = create_instance(nullptr);
    std::vector<PhysicalDeviceInfo> out;
    const auto devices = physical_devices(instance.get());
    for (std::size_t i = 0; i < devices.size(); ++i) {
        out.push_back(describe_device(devices[i], i));
    }
    return out;
}

PhysicalDeviceInfo select_device(const std::string& spec) {
    return choose(list_devices(), spec, {});
}

DeviceChoice choose_device(VkInstance instance, VkSurfaceKHR surface, const std::string& spec,
                           DevicePurpose purpose) {
    const bool marching = purpose == DevicePurpose::ray_marching;
    const auto devices = physical_devices(instance);
    std::vector<PhysicalDeviceInfo> infos;
    for (std::size_t i = 0; i < devices.size(); ++i) {
        infos.push_back(describe_device(devices[i], i));
        if (!marching) {
            // Only presenting: the ray marcher's needs do not apply, Vulkan 1.1 does.
            PhysicalDeviceInfo& d = infos.back();
            d.rejected = d.api_version < VK_API_VERSION_1_1
                             ? "supports only Vulkan " + d.api + " (1.1 needed)"
                             : "";
        }
    }
    std::vector<std::uint32_t> families(devices.size(), 0);
    std::vector<bool> timestamps(devices.size(), false);
    const auto can_present = [&](const PhysicalDeviceInfo& d) -> std::string {
        if (surface == VK_NULL_HANDLE) {
            return "";
        }
        if (!d.has_extension(VK_KHR_SWAPCHAIN_EXTENSION_NAME)) {
            return "lacks VK_KHR_swapchain";
        }
        bool ts = false;
        const std::string why =
            present_family(devices[d.index], surface, marching, families[d.index], ts);
        timestamps[d.index] = ts;
        return why;
    };
    DeviceChoice c;
    c.info = choose(infos, spec, can_present);
    c.physical = devices[c.info.index];
    if (surface != VK_NULL_HANDLE) {
        c.family = families[c.info.index];
        c.info.timestamps = c.info.timestamps && timestamps[c.info.index];
    } else {
        bool ts = false;
        compute_family(c.physical, c.family, ts);
    }
    return c;
}

Context::Context(const ContextOptions& options) {
    const bool presenting = static_cast<bool>(options.make_surface);
    instance_ = create_instance(options.validation, options.instance_extensions);
    try {
        if (presenting) {
            surface_ = options.make_surface(instance_.get());
        }
        // Presenting: the window's surface from a queue that also ray-marches.
        const DeviceChoice choice =
            choose_device(instance_.get(), surface_, options.device, DevicePurpose::ray_marching);
        info_ = choice.info;
        physical_ = choice.physical;
        family_ = choice.family;
        VkPhysicalDeviceProperties props{};
        vkGetPhysicalDeviceProperties(physical_, &props);
        timestamp_period_ = props.limits.timestampPeriod;
        vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);

        const float priority = 1.0f;
        VkDeviceQueueCreateInfo q{};
        q.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
        q.queueFamilyIndex = family_;
        q.queueCount = 1;
        q.pQueuePriorities = &priority;
        // External memory (DESIGN §2 sharing paths 1 and 2) where the device has it.
        std::vector<const char*> extensions;
        if (presenting) {
            extensions.push_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
            enabled_.emplace_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
        }
        for (const char* ext : {VK_KHR_EXTERNAL_MEMORY_FD_EXTENSION_NAME,
                                VK_EXT_EXTERNAL_MEMORY_HOST_EXTENSION_NAME}) {
            if (info_.has_extension(ext)) {
                extensions.push_back(ext);
                enabled_.emplace_back(ext);
            }
        }
        VkDeviceCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
        info.queueCreateInfoCount = 1;
        info.pQueueCreateInfos = &q;
        info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
        info.ppEnabledExtensionNames = extensions.data();
        check(vkCreateDevice(physical_, &info, nullptr, &device_), "vkCreateDevice", info_.name);
        vkGetDeviceQueue(device_, family_, 0, &queue_);

        VkCommandPoolCreateInfo pool{};
        pool.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
        pool.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
        pool.queueFamilyIndex = family_;
        VkCommandPool handle = VK_NULL_HANDLE;
        check(vkCreateCommandPool(device_, &pool, nullptr, &handle), "vkCreateCommandPool");
        pool_ = Owned<VkCommandPool>(device_, handle, vkDestroyCommandPool);
    } catch (...) {
        pool_.reset();
        if (device_ != VK_NULL_HANDLE) {
            vkDestroyDevice(device_, nullptr);
        }
        if (surface_ != VK_NULL_HANDLE) {
            vkDestroySurfaceKHR(instance_.get(), surface_, nullptr);
        }
        throw;  // instance_ destroys the instance
    }
}

Context::~Context() {
    if (device_ != VK_NULL_HANDLE) {
        vkDeviceWaitIdle(device_);
        finish(submitted_);
    }
    pool_.reset();
    if (device_ != VK_NULL_HANDLE) {
        vkDestroyDevice(device_, nullptr);
    }
    if (surface_ != VK_NULL_HANDLE) {
        vkDestroySurfaceKHR(instance_.get(), surface_, nullptr);
    }
}

std::uint32_t Context::memory_type(std::uint32_t allowed, MemoryIntent intent,
                                   const std::string& what) const {
    const VkMemoryPropertyFlags host =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    VkMemoryPropertyFlags required = 0, preferred = 0;
    switch (intent) {
        case MemoryIntent::device_local:
            preferred = VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
            break;
        case MemoryIntent::upload:
            required = host;
            break;
        case MemoryIntent::readback:
            required = host;
            preferred = VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
            break;
    }
    int fallback = -1;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
        const VkMemoryPropertyFlags f = memory_.memoryTypes[i].propertyFlags;
        if ((allowed & (1u << i)) == 0 || (f & required) != required) {
            continue;
        }
        if ((f & preferred) == preferred) {
            return i;
        }
        if (fallback < 0) {
            fallback = static_cast<int>(i);
        }
    }
    if (fallback < 0) {
        throw VkError("vkAllocateMemory", VK_ERROR_FEATURE_NOT_PRESENT,
                      "no memory type fits " + what);
    }
    return static_cast<std::uint32_t>(fallback);
}

Owned<VkDeviceMemory> Context::allocate(const VkMemoryRequirements& req, MemoryIntent intent,
                                        const std::string& what) {
    VkMemoryAllocateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    info.allocationSize = req.size;
    info.memoryTypeIndex = memory_type(req.memoryTypeBits, intent, what);
    VkDeviceMemory memory = VK_NULL_HANDLE;
    check(vkAllocateMemory(device_, &info, nullptr, &memory), "vkAllocateMemory",
          what + ", " + std::to_string(req.size) + " bytes");
    return Owned<VkDeviceMemory>(device_, memory, vkFreeMemory);
}

bool Context::enabled(const std::string& extension) const {
    return std::find(enabled_.begin(), enabled_.end(), extension) != enabled_.end();
}

VkMemoryRequirements Context::external_buffer_requirements(
    VkDeviceSize size, VkBufferUsageFlags usage, VkExternalMemoryHandleTypeFlags handle_types,
    const std::string& what) {
    Buffer probe = make_external_buffer(size, usage, handle_types, what);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, probe.get(), &req);
    return req;
}

Buffer Context::make_external_buffer(VkDeviceSize size, VkBufferUsageFlags usage,
                                     VkExternalMemoryHandleTypeFlags handle_types,
                                     const std::string& what) {
    Buffer b;
    b.size_ = size;
    VkExternalMemoryBufferCreateInfo external{};
    external.sType = VK_STRUCTURE_TYPE_EXTERNAL_MEMORY_BUFFER_CREATE_INFO;
    external.handleTypes = handle_types;
    VkBufferCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    info.pNext = &external;
    info.size = std::max<VkDeviceSize>(size, 4);
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer handle = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &info, nullptr, &handle), "vkCreateBuffer",
          what + ", " + std::to_string(size) + " bytes of external memory");
    b.buffer_ = Owned<VkBuffer>(device_, handle, vkDestroyBuffer);
    return b;
}

void Context::bind(const Buffer& buffer, VkDeviceMemory memory, VkDeviceSize offset,
                   const std::string& what) {
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, buffer.get(), &req);
    if (offset % req.alignment != 0) {
        throw VkError("vkBindBufferMemory", VK_ERROR_VALIDATION_FAILED_EXT,
                      what + ": offset " + std::to_string(offset) + " is not a multiple of " +
                          std::to_string(req.alignment));
    }
    check(vkBindBufferMemory(device_, buffer.get(), memory, offset), "vkBindBufferMemory", what);
}

std::uint32_t Context::memory_type_for(std::uint32_t allowed, VkMemoryPropertyFlags preferred,
                                       const std::string& what) const {
    int fallback = -1;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
        if ((allowed & (1u << i)) == 0) {
            continue;
        }
        if ((memory_.memoryTypes[i].propertyFlags & preferred) == preferred) {
            return i;
        }
        if (fallback < 0) {
            fallback = static_cast<int>(i);
        }
    }
    if (fallback < 0) {
        throw VkError("vkAllocateMemory", VK_ERROR_FEATURE_NOT_PRESENT,
                      "no memory type fits " + what);
    }
    return static_cast<std::uint32_t>(fallback);
}

Buffer Context::make_buffer(VkDeviceSize size, VkBufferUsageFlags usage, MemoryIntent intent,
                            const std::string& what) {
    Buffer b;
    b.size_ = size;
    VkBufferCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    info.size = std::max<VkDeviceSize>(size, 4);
    info.usage = usage;
    info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VkBuffer handle = VK_NULL_HANDLE;
    check(vkCreateBuffer(device_, &info, nullptr, &handle), "vkCreateBuffer",
          what + ", " + std::to_string(size) + " bytes");
    b.buffer_ = Owned<VkBuffer>(device_, handle, vkDestroyBuffer);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device_, handle, &req);
    b.memory_ = allocate(req, intent, what);
    check(vkBindBufferMemory(device_, handle, b.memory_.get(), 0), "vkBindBufferMemory", what);
    const std::uint32_t type = memory_type(req.memoryTypeBits, intent, what);
    const VkMemoryPropertyFlags host =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    if ((memory_.memoryTypes[type].propertyFlags & host) == host) {
        check(vkMapMemory(device_, b.memory_.get(), 0, VK_WHOLE_SIZE, 0, &b.mapped_), "vkMapMemory",
              what);
    }
    return b;
}

void Context::upload(const Buffer& dst, const void* bytes, VkDeviceSize size, VkDeviceSize offset) {
    if (size == 0) {
        return;
    }
    if (dst.host_visible()) {
        std::memcpy(static_cast<std::uint8_t*>(dst.data()) + offset, bytes, size);
        return;
    }
    const VkDeviceSize chunk = std::min<VkDeviceSize>(size, VkDeviceSize{64} << 20);
    Buffer staging =
        make_buffer(chunk, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryIntent::upload, "staging");
    for (VkDeviceSize done = 0; done < size; done += chunk) {
        const VkDeviceSize n = std::min(chunk, size - done);
        std::memcpy(staging.data(), static_cast<const std::uint8_t*>(bytes) + done, n);
        try {
            submit_and_wait(
                [&](VkCommandBuffer cmd) {
                    VkBufferCopy region{0, offset + done, n};
                    vkCmdCopyBuffer(cmd, staging.get(), dst.get(), 1, &region);
                },
                "upload");
        } catch (...) {
            retire(std::move(staging));  // the copy may still read it
            throw;
        }
    }
}

void Context::submit_and_wait(const std::function<void(VkCommandBuffer)>& record,
                              const std::string& what, std::chrono::nanoseconds timeout) {
    collect_retired(false);
    VkCommandBufferAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    alloc.commandPool = pool_.get();
    alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    alloc.commandBufferCount = 1;
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    check(vkAllocateCommandBuffers(device_, &alloc, &cmd), "vkAllocateCommandBuffers", what);
    // Freed on every way out except a failed wait, which retires it instead.
    struct FreeCmd {
        VkDevice device;
        VkCommandPool pool;
        VkCommandBuffer cmd;
        ~FreeCmd() {
            if (cmd != VK_NULL_HANDLE) {
                vkFreeCommandBuffers(device, pool, 1, &cmd);
            }
        }
    } free_cmd{device_, pool_.get(), cmd};
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer", what);
    record(cmd);
    check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer", what);

    VkFenceCreateInfo fence_info{};
    fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence_handle = VK_NULL_HANDLE;
    check(vkCreateFence(device_, &fence_info, nullptr, &fence_handle), "vkCreateFence", what);
    Owned<VkFence> fence(device_, fence_handle, vkDestroyFence);
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.commandBufferCount = 1;
    info.pCommandBuffers = &cmd;
    submit(info, fence.get(), what);
    const std::uint64_t serial = submitted_;
    const std::uint64_t ns =
        timeout == std::chrono::nanoseconds::max()
            ? UINT64_MAX
            : static_cast<std::uint64_t>(std::max<std::int64_t>(timeout.count(), 0));
    const VkResult r = vkWaitForFences(device_, 1, &fence_handle, VK_TRUE, ns);
    if (r != VK_SUCCESS) {
        // The GPU may still run the command buffer (and read what it refers to): both stay
        // alive until its fence signals.
        struct Submission {
            Owned<VkFence> fence;
            VkDevice device;
            VkCommandPool pool;
            VkCommandBuffer cmd;
            Submission(Owned<VkFence> f, VkDevice d, VkCommandPool p, VkCommandBuffer c)
                : fence(std::move(f)), device(d), pool(p), cmd(c) {}
            Submission(Submission&& o) noexcept
                : fence(std::move(o.fence)),
                  device(o.device),
                  pool(o.pool),
                  cmd(std::exchange(o.cmd, VK_NULL_HANDLE)) {}
            ~Submission() {
                if (cmd != VK_NULL_HANDLE) {
                    vkFreeCommandBuffers(device, pool, 1, &cmd);
                }
            }
        };
        retire(Submission(std::move(fence), device_, pool_.get(), cmd));
        free_cmd.cmd = VK_NULL_HANDLE;
        throw VkError("vkWaitForFences", r, what);
    }
    finish(serial);
}

std::uint64_t Context::submit_unwaited(const std::function<void(VkCommandBuffer)>& record,
                                       const std::string& what) {
    collect_retired(false);
    // The command buffer and fence of a submission nobody waits for: freed once it finished.
    struct Unwaited {
        VkDevice device;
        VkCommandPool pool;
        VkCommandBuffer cmd = VK_NULL_HANDLE;
        Owned<VkFence> fence;
        Unwaited(VkDevice d, VkCommandPool p) : device(d), pool(p) {}
        Unwaited(Unwaited&& o) noexcept
            : device(o.device),
              pool(o.pool),
              cmd(std::exchange(o.cmd, VK_NULL_HANDLE)),
              fence(std::move(o.fence)) {}
        ~Unwaited() {
            if (cmd != VK_NULL_HANDLE) {
                vkFreeCommandBuffers(device, pool, 1, &cmd);
            }
        }
    };
    Unwaited u(device_, pool_.get());
    VkCommandBufferAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
    alloc.commandPool = pool_.get();
    alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    alloc.commandBufferCount = 1;
    check(vkAllocateCommandBuffers(device_, &alloc, &u.cmd), "vkAllocateCommandBuffers", what);
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    check(vkBeginCommandBuffer(u.cmd, &begin), "vkBeginCommandBuffer", what);
    record(u.cmd);
    check(vkEndCommandBuffer(u.cmd), "vkEndCommandBuffer", what);
    VkFenceCreateInfo fence_info{};
    fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
    VkFence fence = VK_NULL_HANDLE;
    check(vkCreateFence(device_, &fence_info, nullptr, &fence), "vkCreateFence", what);
    u.fence = Owned<VkFence>(device_, fence, vkDestroyFence);
    VkSubmitInfo info{};
    info.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    info.commandBufferCount = 1;
    info.pCommandBuffers = &u.cmd;
    submit(info, fence, what);
    const std::uint64_t serial = submitted_;
    retire(std::move(u));
    return serial;
}

void Context::submit(const VkSubmitInfo& info, VkFence fence, const std::string& what) {
    if (injected_failure_ != VK_SUCCESS) {
        const VkResult r = std::exchange(injected_failure_, VK_SUCCESS);
        throw VkError("vkQueueSubmit", r, what + " (injected failure)");
    }
    check(vkQueueSubmit(queue_, 1, &info, fence), "vkQueueSubmit", what);
    pending_.push_back(Pending{++submitted_, fence});
}

void Context::wait(VkFence fence, const std::string& what) {
    check(vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences", what);
    std::uint64_t serial = 0;
    for (const Pending& p : pending_) {
        if (p.fence == fence) {
            serial = std::max(serial, p.serial);
        }
    }
    finish(serial);
}

void Context::finish(std::uint64_t serial) {
    // A fence's signal covers every earlier submission to the queue.
    finished_ = std::max(finished_, serial);
    std::erase_if(pending_, [&](const Pending& p) { return p.serial <= finished_; });
    std::erase_if(retired_, [&](const Retired& r) { return r.serial <= finished_; });
}

void Context::retire_erased(std::shared_ptr<void> resource) {
    if (submitted_ == finished_) {
        return;  // nothing in flight: `resource` goes now
    }
    retired_.push_back(Retired{submitted_, std::move(resource)});
}

bool Context::busy() {
    return !finished(submitted_);
}

bool Context::finished(std::uint64_t serial) {
    if (serial > finished_) {
        collect_retired(false);
    }
    return serial <= finished_;
}

void Context::wait_for(std::uint64_t serial) {
    if (serial <= finished_) {
        return;
    }
    // Submissions are pending in serial order; a fence covers every earlier submission.
    for (const Pending& p : pending_) {
        if (p.serial >= serial) {
            const VkFence fence = p.fence;
            const std::uint64_t covered = p.serial;
            check(vkWaitForFences(device_, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences",
                  "the frames in flight");
            finish(covered);
            return;
        }
    }
    if (!pending_.empty()) {
        wait_for(pending_.back().serial);
    }
}

void Context::wait_frames_in_flight() {
    collect_retired(true);
}

std::size_t Context::retired_in_flight() {
    collect_retired(false);
    return retired_.size();
}

void Context::collect_retired(bool wait) {
    if (wait && finished_ < submitted_) {
        // The latest submission's fence covers every earlier one: no device idle.
        if (!pending_.empty()) {
            const Pending last = pending_.back();
            check(vkWaitForFences(device_, 1, &last.fence, VK_TRUE, UINT64_MAX), "vkWaitForFences",
                  "the frames in flight");
            finish(last.serial);
        }
        return;
    }
    // The latest submission whose fence signalled, or never will (a lost device).
    for (auto it = pending_.rbegin(); it != pending_.rend(); ++it) {
        if (vkGetFenceStatus(device_, it->fence) != VK_NOT_READY) {
            finish(it->serial);
            return;
        }
    }
}

}  // namespace voxfield::vk
