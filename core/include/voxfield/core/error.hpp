#pragma once
// Exceptions shared by every module. Libraries throw; only viewer/ prints or exits.
#include <stdexcept>
#include <string>

namespace voxfield {

// Bad input from the user: a file that cannot be read or parsed, an unknown name, a value
// out of range. The command line maps it to exit code 2.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

}  // namespace voxfield
