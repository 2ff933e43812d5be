// `voxfield`: the command-line front end (viewer/cli, the only code that prints or exits).
#include <signal.h>

#include <csignal>
#include <cstdio>
#include <iostream>
#include <string>
#include <string_view>

#include "cli_util.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/vk/context.hpp"

namespace {

// Ctrl-C, SIGTERM or SIGHUP while outputs are being written: their temporaries are removed
// (no destructor runs), then the signal ends the process as it would have.
extern "C" void end_on_signal(int sig) {
    voxfield::remove_output_temporaries();
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

// An error on one line, whatever text a message took from a file: control characters (a
// newline, a tab) as \xNN.
std::string one_line(const char* what) {
    std::string s;
    for (const char* p = what; *p != '\0'; ++p) {
        const auto c = static_cast<unsigned char>(*p);
        s += c < 0x20 || c == 0x7f ? voxfield::printable(std::string_view(p, 1))
                                   : std::string(1, *p);
    }
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    using namespace voxfield;
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) {
        // A signal the caller ignores (nohup's SIGHUP, a script's background job's SIGINT)
        // stays ignored.
        struct sigaction old {};
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler != SIG_IGN) {
            std::signal(sig, end_on_signal);
        }
    }
    CLI::App app{"voxfield: fast, exact distance fields for voxel worlds on any OpenCL device"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("voxfield ") + cli::commit());
    std::vector<cli::Command> commands = {
        cli::add_devices(app), cli::add_generate(app), cli::add_replay(app), cli::add_simulate(app),
        cli::add_bench(app),   cli::add_render(app),   cli::add_view(app),   cli::add_info(app)};
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::cerr << "voxfield: " << one_line(e.what()) << " (see --help)\n";
        return 2;
    }
    try {
        for (auto& c : commands) {
            if (c.app->parsed()) {
                return c.run();
            }
        }
        return 2;
    } catch (const InputError& e) {
        std::cerr << "voxfield: " << one_line(e.what()) << '\n';
        return 2;
    } catch (const ocl::BuildError& e) {
        std::cerr << "voxfield: " << one_line(e.what()) << '\n';
        return 1;
    } catch (const ocl::ClError& e) {
        std::cerr << "voxfield: device failure: " << one_line(e.what()) << '\n';
        return 1;
    } catch (const vk::VkError& e) {
        std::cerr << "voxfield: Vulkan device failure: " << one_line(e.what()) << '\n';
        return 1;
    } catch (const vk::DeviceSelectionError& e) {
        std::cerr << "voxfield: " << one_line(e.what()) << '\n';
        return 2;  // as OpenCL's DeviceSelectionError: no device (driver) serves the request
    } catch (const std::bad_alloc&) {
        std::cerr << "voxfield: out of host memory\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "voxfield: " << one_line(e.what()) << '\n';
        return 1;
    }
}
