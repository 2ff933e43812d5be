#pragma once
// 256 RGBA colours indexed by voxel value (index 0 is air and never drawn).
#include <array>
#include <cstdint>

namespace voxfield {

struct Rgba {
    std::uint8_t r = 0, g = 0, b = 0, a = 255;
    friend bool operator==(const Rgba&, const Rgba&) = default;
};

// RGB332 byte used by the packed32 field format: (r>>5)<<5 | (g>>5)<<2 | (b>>6).
std::uint8_t to_rgb332(Rgba c);

class Palette {
  public:
    Palette();  // MagicaVoxel's default palette

    static Palette magicavoxel_default();
    // The dissertation's 11 named colours at indices 1..11 (Black, White, Grey, Red, Pink,
    // Purple, Blue, Cyan, Turquoise, Green, Yellow), expanded from their RGB332 values so
    // that to_rgb332 gives back the dissertation's bytes; the rest is MagicaVoxel's default.
    static Palette dissertation();

    const Rgba& operator[](std::uint8_t index) const { return colours_[index]; }
    Rgba& operator[](std::uint8_t index) { return colours_[index]; }

    // to_rgb332 of every entry, with entry 0 (air) forced to 0.
    std::array<std::uint8_t, 256> rgb332_table() const;

  private:
    std::array<Rgba, 256> colours_{};
};

}  // namespace voxfield
