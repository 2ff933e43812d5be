// `voxfield devices [--json]`: every OpenCL device, with the index --device accepts, and the
// OpenCL -> Vulkan sharing path (DESIGN §2) that `render` would use with the default devices.
#include <exception>
#include <iostream>
#include <string>

#include "cli_util.hpp"
#include "voxfield/pipeline/render_field.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::cli {

namespace {

// The OpenCL -> Vulkan sharing path from OpenCL device `device` to the default Vulkan device
// (what `render --field compact` would use), or why it cannot be said.
struct Sharing {
    std::string path, vulkan, why_not;
    std::string sync;  // pipeline::FieldSync: how that path orders edits ("" unknown)
};

Sharing sharing_of(const ocl::DeviceInfo& device) {
    try {
        ocl::Context cl_ctx(device);
        vk::Context vk_ctx;
        std::string why_not;
        const vk::SharingPath path = pipeline::choose_sharing_path(cl_ctx, vk_ctx, why_not);
        std::string sync_why_not;
        const pipeline::FieldSync sync =
            pipeline::choose_field_sync(cl_ctx, vk_ctx, path, sync_why_not);
        return {vk::describe(path), vk_ctx.info().name,
                why_not.empty() ? "" : why_not.substr(0, why_not.size() - 2),
                pipeline::to_string(sync)};
    } catch (const std::exception& e) {
        return {"none", "", e.what(), ""};
    }
}

// "sharing: path N: ... (OpenCL X, Vulkan Y)", or why it cannot be said.
std::string sharing_line() {
    try {
        const ocl::DeviceInfo device = ocl::select_device("");
        const Sharing s = sharing_of(device);
        if (s.vulkan.empty()) {
            return "sharing: none (" + s.why_not + ")";
        }
        return "sharing: " + s.path + " (OpenCL " + device.name + ", Vulkan " + s.vulkan +
               "; render --field compact)" + (s.why_not.empty() ? "" : " [" + s.why_not + "]");
    } catch (const std::exception& e) {
        return std::string("sharing: none (") + e.what() + ")";
    }
}

}  // namespace

Command add_devices(CLI::App& root) {
    auto* app = root.add_subcommand("devices", "List OpenCL devices and their indices");
    auto json = std::make_shared<bool>(false);
    app->add_flag("--json", *json,
                  "Print the list as JSON, each device with its sharing path to the default "
                  "Vulkan device (path, vulkan_device, why_not, sync)");
    return {app, [json] {
                const auto devices = ocl::list_devices();
                if (*json) {
                    nlohmann::json out = nlohmann::json::array();
                    for (const auto& d : devices) {
                        nlohmann::json j = device_json(d);
                        const Sharing s = sharing_of(d);
                        j["sharing"] = {
                            {"path", s.path},
                            {"vulkan_device",
                             s.vulkan.empty() ? nlohmann::json() : nlohmann::json(s.vulkan)},
                            {"why_not", s.why_not},
                            {"sync", s.sync.empty() ? nlohmann::json() : nlohmann::json(s.sync)}};
                        out.push_back(std::move(j));
                    }
                    std::cout << out.dump(2) << '\n';
                    return 0;
                }
                if (devices.empty()) {
                    std::cout << "no OpenCL devices (install an ICD such as pocl-opencl-icd)\n";
                    return 0;
                }
                for (const auto& d : devices) {
                    std::cout << d.index << ": " << d.name << "  [" << d.type << ", " << d.platform
                              << ", " << d.version << ", " << d.compute_units << " CUs, "
                              << (d.global_mem >> 20) << " MiB]"
                              << (d.available ? "" : " (not available)") << '\n';
                }
                std::cout << sharing_line() << '\n';
                return 0;
            }};
}

}  // namespace voxfield::cli
