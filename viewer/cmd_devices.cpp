// `voxfield devices [--json]`: every OpenCL device, with the index --device accepts.
#include <iostream>

#include "cli_util.hpp"

namespace voxfield::cli {

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
                return 0;
            }};
}

}  // namespace voxfield::cli
