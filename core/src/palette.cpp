// Palettes: MagicaVoxel's default (its .vox spec, section "Default Palette") and the
// dissertation's 11 named RGB332 colours (seed-code-notes, "Data layout").
#include "voxfield/core/palette.hpp"

#include <array>
#include <cstdint>

namespace voxfield {

std::uint8_t to_rgb332(Rgba c) {
    return static_cast<std::uint8_t>(((c.r >> 5) << 5) | ((c.g >> 5) << 2) | (c.b >> 6));
}

namespace {

Rgba rgba(unsigned r, unsigned g, unsigned b, unsigned a = 255) {
    return Rgba{static_cast<std::uint8_t>(r), static_cast<std::uint8_t>(g),
                static_cast<std::uint8_t>(b), static_cast<std::uint8_t>(a)};
}

// MagicaVoxel's default palette. The spec lists it as 0xAABBGGRR words; its structure is:
// index 0 transparent black; 1..215 the 6x6x6 cube of {ff,cc,99,66,33,00} with red slowest
// and blue fastest (the final all-zero entry dropped); then ramps ee,dd,bb,aa,88,77,55,44,
// 22,11 of red (216..225), green (226..235), blue (236..245) and grey (246..255).
std::array<Rgba, 256> make_default() {
    std::array<Rgba, 256> p{};
    p[0] = rgba(0, 0, 0, 0);
    std::size_t i = 1;
    for (unsigned r = 0; r < 6; ++r) {
        for (unsigned g = 0; g < 6; ++g) {
            for (unsigned b = 0; b < 6; ++b) {
                if (i > 215) {
                    break;
                }
                p[i++] = rgba(0xff - 0x33 * r, 0xff - 0x33 * g, 0xff - 0x33 * b);
            }
        }
    }
    const std::array<unsigned, 10> ramp = {0xee, 0xdd, 0xbb, 0xaa, 0x88,
                                           0x77, 0x55, 0x44, 0x22, 0x11};
    for (std::size_t k = 0; k < ramp.size(); ++k) {
        p[216 + k] = rgba(ramp[k], 0, 0);
        p[226 + k] = rgba(0, ramp[k], 0);
        p[236 + k] = rgba(0, 0, ramp[k]);
        p[246 + k] = rgba(ramp[k], ramp[k], ramp[k]);
    }
    return p;
}

// Expands 3/3/2-bit channels to 8 bits (v * 255 / 7 and v * 255 / 3, rounded).
Rgba expand332(unsigned r3, unsigned g3, unsigned b2) {
    return rgba((r3 * 255 + 3) / 7, (g3 * 255 + 3) / 7, (b2 * 255 + 1) / 3);
}

}  // namespace

Palette::Palette() : colours_(make_default()) {}

Palette Palette::magicavoxel_default() {
    return Palette();
}

Palette Palette::dissertation() {
    Palette p;
    // Black, White, Grey, Red, Pink, Purple, Blue, Cyan, Turquoise, Green, Yellow.
    const std::array<std::array<unsigned, 3>, 11> rgb332 = {{{0, 0, 0},
                                                             {7, 7, 3},
                                                             {5, 5, 2},
                                                             {7, 0, 0},
                                                             {7, 0, 2},
                                                             {5, 0, 3},
                                                             {0, 0, 3},
                                                             {0, 7, 3},
                                                             {0, 7, 2},
                                                             {0, 7, 0},
                                                             {7, 7, 0}}};
    for (std::size_t k = 0; k < rgb332.size(); ++k) {
        p.colours_[k + 1] = expand332(rgb332[k][0], rgb332[k][1], rgb332[k][2]);
    }
    return p;
}

std::array<std::uint8_t, 256> Palette::rgb332_table() const {
    std::array<std::uint8_t, 256> t{};
    for (std::size_t i = 1; i < 256; ++i) {
        t[i] = to_rgb332(colours_[i]);
    }
    t[0] = 0;
    return t;
}

}  // namespace voxfield
