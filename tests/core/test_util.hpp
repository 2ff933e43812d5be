#pragma once
// Helpers shared by the core tests: a temporary folder and whole-file byte IO.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield::test {

class TempDir {
  public:
    TempDir() {
        std::random_device rd;
        const auto base = std::filesystem::temp_directory_path();
        for (int i = 0; i < 100; ++i) {
            path_ = base / ("voxfield-core-test-" + std::to_string(rd()) + std::to_string(i));
            if (std::filesystem::create_directory(path_)) {
                return;
            }
        }
        throw std::runtime_error("cannot create a temporary folder");
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const std::filesystem::path& path() const { return path_; }
    std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

  private:
    std::filesystem::path path_;
};

inline void write_bytes(const std::filesystem::path& p, const std::vector<std::uint8_t>& b) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    ASSERT_TRUE(out.good()) << p;
}

inline void write_text(const std::filesystem::path& p, const std::string& s) {
    write_bytes(p, std::vector<std::uint8_t>(s.begin(), s.end()));
}

inline std::vector<std::uint8_t> read_bytes(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// Concatenation by append: GCC 12 gives a false -Wrestrict on "literal" + std::string&&.
inline std::string cat(std::initializer_list<std::string_view> parts) {
    std::string s;
    for (auto part : parts) {
        s.append(part);
    }
    return s;
}

inline void put_u32(std::vector<std::uint8_t>& b, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) {
        b.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
    }
}

// Runs `f`, expects an InputError whose message contains every one of `parts`.
template <typename F>
void expect_input_error(F&& f, const std::vector<std::string>& parts) {
    try {
        f();
        ADD_FAILURE() << "expected InputError containing '" << (parts.empty() ? "" : parts[0])
                      << "'";
    } catch (const InputError& e) {
        const std::string msg = e.what();
        for (const auto& part : parts) {
            EXPECT_NE(msg.find(part), std::string::npos)
                << "message '" << msg << "' lacks '" << part << "'";
        }
        EXPECT_EQ(msg.find('\n'), std::string::npos) << "message is not one line: " << msg;
    }
}

}  // namespace voxfield::test
