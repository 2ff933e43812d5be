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

// "sharing: path N: ... (OpenCL X, Vulkan Y)", or why it cannot be said.
std::string sharing_line() {
    try {
        ocl::Context cl_ctx(ocl::select_device(""));
        vk::Context vk_ctx;
        std::string why_not;
        const vk::SharingPath path = pipeline::choose_sharing_path(cl_ctx, vk_ctx, why_not);
        return "sharing: " + vk::describe(path) + " (OpenCL " + cl_ctx.info().name + ", Vulkan " +
               vk_ctx.info().name + "; render --field compact)" +
               (why_not.empty() ? "" : " [" + why_not.substr(0, why_not.size() - 2) + "]");
    } catch (const std::exception& e) {
        return std::string("sharing: none (") + e.what() + ")";
    }
}

}  // namespace

Command add_devices(CLI::App& root) {
    auto* app = root.add_subcommand("devices", "List OpenCL devices and their indices");
    auto json = std::make_shared<bool>(false);
    app->add_flag("--json", *json, "Print the list as JSON");
    return {app, [json] {
                const auto devices = ocl::list_devices();
                if (*json) {
                    nlohmann::json out = nlohmann::json::array();
                    for (const auto& d : devices) {
                        out.push_back(device_json(d));
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
