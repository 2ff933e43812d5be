#pragma once
// Exceptions shared by every module. Libraries throw; only viewer/ prints or exits.
#include <stdexcept>
#include <string>
#include <string_view>

namespace voxfield {

// Bad input from the user: a file that cannot be read or parsed, an unknown name, a value
// out of range. The command line maps it to exit code 2.
class InputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Text from a file (a name, a value) for a one-line message: printable ASCII as it is, anything
// else (a newline, a NUL, a byte above 0x7e) and the quote and backslash as \xNN.
inline std::string printable(std::string_view text) {
    std::string s;
    for (const char ch : text) {
        const auto c = static_cast<unsigned char>(ch);
        if (c >= 0x20 && c < 0x7f && c != '\'' && c != '\\') {
            s += ch;
        } else {
            const char* hex = "0123456789abcdef";
            s += "\\x";
            s += hex[c >> 4];
            s += hex[c & 15];
        }
    }
    return s;
}

}  // namespace voxfield
