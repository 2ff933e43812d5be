// Plugins loaded on first use (voxfield/core/plugin.hpp).
#include "voxfield/core/plugin.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <system_error>
#include <utility>

namespace voxfield {

namespace fs = std::filesystem;

const PluginHeader* load_plugin(const PluginSpec& spec) {
    std::vector<fs::path> paths;
    const char* named = spec.env.empty() ? nullptr : std::getenv(spec.env.c_str());
    if (named != nullptr && *named != '\0') {
        std::error_code ec;
        const fs::path absolute = fs::absolute(named, ec);
        paths.push_back(ec ? fs::path(named) : absolute);
    } else {
        for (const fs::path& dir : spec.places) {
            if (!dir.empty()) {
                paths.push_back(dir / spec.file);
            }
        }
    }
    std::string tried;
    std::vector<std::string> seen;
    for (const fs::path& path : paths) {
        const std::string p = path.string();
        if (std::find(seen.begin(), seen.end(), p) != seen.end()) {
            continue;
        }
        seen.push_back(p);
        std::string why;
        std::error_code ec;
        if (!fs::exists(path, ec)) {
            why = "not there";
        } else if (void* handle = dlopen(p.c_str(), RTLD_NOW | RTLD_LOCAL); handle == nullptr) {
            const char* e = dlerror();
            why = e != nullptr ? e : "dlopen failed";
        } else if (void* entry = dlsym(handle, spec.entry.c_str()); entry == nullptr) {
            why = "no entry " + spec.entry;
            dlclose(handle);
        } else {
            const auto get = reinterpret_cast<const PluginHeader* (*)()>(entry);
            const PluginHeader* table = get();
            if (table == nullptr || table->build_id == nullptr ||
                spec.build_id != table->build_id) {
                why = "of another build (" +
                      std::string(table != nullptr && table->build_id != nullptr ? table->build_id
                                                                                 : "none") +
                      ", this one is " + spec.build_id + ")";
                dlclose(handle);
            } else {
                return table;  // the handle stays open for the process's life
            }
        }
        tried += (tried.empty() ? "" : "; ") + p + ": " + why;
    }
    throw std::runtime_error(
        spec.what + " (" + spec.file + ") could not be loaded" +
        (tried.empty() ? std::string(": no place to look") : " from any place tried: " + tried) +
        (spec.env.empty() ? std::string() : " (set " + spec.env + " to its path)"));
}

PluginSpec project_plugin(std::string what, std::string file, std::string env, std::string entry) {
    PluginSpec spec;
    spec.what = std::move(what);
    spec.file = std::move(file);
    spec.env = std::move(env);
    spec.places = {plugin_dir_beside_binary("../lib/voxfield"),
                   plugin_dir_beside_binary(VOXFIELD_PLUGIN_INSTALL_REL), VOXFIELD_PLUGIN_BUILD_DIR,
                   VOXFIELD_PLUGIN_INSTALL_DIR};
    spec.entry = std::move(entry);
    spec.build_id = VOXFIELD_PLUGIN_BUILD_ID;
    return spec;
}

fs::path plugin_dir_beside_binary(const fs::path& relative) {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) {
        return {};
    }
    return (exe.parent_path() / relative).lexically_normal();
}

}  // namespace voxfield
