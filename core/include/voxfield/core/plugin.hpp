#pragma once
// Shared objects loaded on first use (dlopen), for libraries too costly to load at every
// process start: linking OpenVDB makes the dynamic loader bind about 57 000 symbols, about 45 ms
// before main on this project's VM, paid by every command whether it reads a .vdb or not. A
// plugin's entry returns a table whose first member is the build's id (a hash of the headers
// whose types cross the boundary), so that a plugin built from other headers (an older install
// beside a newer build tree) is passed over.
#include <filesystem>
#include <string>
#include <vector>

namespace voxfield {

// The first member of every plugin table.
struct PluginHeader {
    const char* build_id;
};

struct PluginSpec {
    std::string what;  // for messages: "the OpenVDB plugin"
    std::string file;  // its file name: "libvoxfield_vdb.so"
    std::string env;   // the environment variable that names its path instead of `places`
                       // (relative to the working folder when not absolute)
    std::vector<std::filesystem::path> places;  // folders looked in, in order
    std::string entry;     // the C symbol of its entry, `const PluginHeader* entry()`
    std::string build_id;  // what the table's build_id must be
};

// The entry's table from the first place that holds a plugin of this build, never unloaded
// (callers keep the table: a function-local static loads it once per process).
// std::runtime_error naming every place tried and why, when none does.
const PluginHeader* load_plugin(const PluginSpec& spec);

// load_plugin's table as the plugin's own type T (whose first member is the PluginHeader).
template <class T>
const T& load_plugin_table(const PluginSpec& spec) {
    return *reinterpret_cast<const T*>(load_plugin(spec));
}

// One of this project's plugins: looked for beside the binary (as the build lays it out, then as
// the install does), in the build folder, in the install prefix; this build's id.
PluginSpec project_plugin(std::string what, std::string file, std::string env, std::string entry);

// The folder `relative` to the running binary's folder ("../lib/voxfield": build/lib/voxfield
// for build/viewer, <prefix>/lib/voxfield for <prefix>/bin), or an empty path when the binary's
// path is unknown.
std::filesystem::path plugin_dir_beside_binary(const std::filesystem::path& relative);

}  // namespace voxfield
