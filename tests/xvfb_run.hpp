#pragma once
// The xvfb-run command line the window tests run under (tests/cli, tests/viewer, tests/vk).
#include <unistd.h>

#include <string>

namespace voxfield::test {

// `xvfb-run -a` takes the first free server number from -n (99 by default; -n first, as
// xvfb-run reads its options in order) on; tests that CTest runs side by side (-j) and start
// the search at the same number can take the same one, and one Xvfb then fails to start or
// one test draws on the other's server. Each process starts its search at its own number.
inline std::string xvfb_run(const std::string& screen) {
    return "xvfb-run -n " + std::to_string(100 + ::getpid() % 20000) + " -a -s '-screen 0 " +
           screen + "'";
}

}  // namespace voxfield::test
