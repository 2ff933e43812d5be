// Vulkan device enumeration and the one device selection (list_devices, select_device,
// choose_device in context.hpp), explaining every rejection.
#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>

#include "instance.hpp"
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
        VkPhysicalDeviceMaintenance4Properties m4{};
        m4.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_4_PROPERTIES;
        m4.pNext = &id;
        const bool maintenance4 = p.apiVersion >= VK_API_VERSION_1_3 ||
                                  info.has_extension(VK_KHR_MAINTENANCE_4_EXTENSION_NAME);
        VkPhysicalDeviceProperties2 p2{};
        p2.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2;
        p2.pNext = maintenance4 ? static_cast<void*>(&m4) : static_cast<void*>(&id);
        vkGetPhysicalDeviceProperties2(d, &p2);
        std::memcpy(info.uuid.data(), id.deviceUUID, VK_UUID_SIZE);
        info.max_buffer_size = maintenance4 ? m4.maxBufferSize : 0;
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
    // Appended piece by piece: GCC 12's -Wrestrict misfires on "#" + std::to_string(...) here.
    std::string s = "#";
    s += std::to_string(d.index);
    s += ' ';
    s += d.name;
    s += " (";
    s += d.type;
    s += ')';
    return s;
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

}  // namespace voxfield::vk
