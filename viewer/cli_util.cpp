#include "cli_util.hpp"

#include <fstream>

#include "voxfield/core/error.hpp"
#include "voxfield_commit.hpp"

namespace voxfield::cli {

void require_output_folder(const std::filesystem::path& path) {
    const auto folder = path.parent_path();
    if (!folder.empty() && !std::filesystem::is_directory(folder)) {
        throw InputError("cannot write '" + path.string() + "': folder '" + folder.string() +
                         "' does not exist");
    }
}

void write_text_file(const std::filesystem::path& path, const std::string& text) {
    require_output_folder(path);
    const auto tmp = std::filesystem::path(path.string() + ".tmp");
    {
        std::ofstream out(tmp);
        out << text;
        out.flush();
        if (!out) {
            out.close();
            std::filesystem::remove(tmp);
            throw InputError("cannot write '" + path.string() + "'");
        }
    }
    std::filesystem::rename(tmp, path);
}

void write_json_file(const std::filesystem::path& path, const nlohmann::json& j) {
    write_text_file(path, j.dump(2) + "\n");
}

nlohmann::json device_json(const ocl::DeviceInfo& d) {
    return {{"index", d.index},
            {"name", d.name},
            {"vendor", d.vendor},
            {"platform", d.platform},
            {"type", d.type},
            {"version", d.version},
            {"driver", d.driver},
            {"compute_units", d.compute_units},
            {"global_mem_bytes", d.global_mem},
            {"max_alloc_bytes", d.max_alloc},
            {"local_mem_bytes", d.local_mem},
            {"max_work_group_size", d.max_work_group},
            {"available", d.available},
            {"extensions", d.extensions}};
}

std::string commit() {
    return VOXFIELD_GIT_COMMIT;
}

}  // namespace voxfield::cli
