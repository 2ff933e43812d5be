// The incremental L1 update's box field on the CPU (box_field.hpp).
#include "voxfield/core/box_field.hpp"

#include <algorithm>
#include <cstddef>

namespace voxfield {

void box_field_transform(std::uint32_t* f, Int3 n) {
    const auto nx = static_cast<std::size_t>(n.x), ny = static_cast<std::size_t>(n.y),
               nz = static_cast<std::size_t>(n.z);
    auto sweep = [f](std::size_t start, std::size_t count, std::size_t stride) {
        std::uint32_t run = kBoxFieldFar;
        for (std::size_t i = 0; i < count; ++i) {
            std::uint32_t& v = f[start + i * stride];
            run = std::min(v, run == kBoxFieldFar ? kBoxFieldFar : run + 1);
            v = run;
        }
        run = kBoxFieldFar;
        for (std::size_t i = count; i-- > 0;) {
            std::uint32_t& v = f[start + i * stride];
            run = std::min(v, run == kBoxFieldFar ? kBoxFieldFar : run + 1);
            v = run;
        }
    };
    for (std::size_t z = 0; z < nz; ++z) {
        for (std::size_t y = 0; y < ny; ++y) {
            sweep((z * ny + y) * nx, nx, 1);
        }
    }
    for (std::size_t z = 0; z < nz; ++z) {
        for (std::size_t x = 0; x < nx; ++x) {
            sweep(z * ny * nx + x, ny, nx);
        }
    }
    for (std::size_t y = 0; y < ny; ++y) {
        for (std::size_t x = 0; x < nx; ++x) {
            sweep(y * nx + x, nz, nx * ny);
        }
    }
}

std::array<std::uint32_t, 27> box_field_boundary_minima(const std::uint32_t* f, Int3 n) {
    const std::size_t size[3] = {static_cast<std::size_t>(n.x), static_cast<std::size_t>(n.y),
                                 static_cast<std::size_t>(n.z)};
    std::array<std::uint32_t, 27> least{};
    for (std::size_t part = 0; part < 27; ++part) {
        std::size_t lo[3], hi[3];
        for (std::size_t a = 0, side = part; a < 3; ++a, side /= 3) {
            lo[a] = side % 3 == 2 ? size[a] - 1 : 0;
            hi[a] = side % 3 == 0 ? 1 : size[a];
        }
        std::uint32_t m = kBoxFieldFar;
        for (std::size_t z = lo[2]; z < hi[2]; ++z) {
            for (std::size_t y = lo[1]; y < hi[1]; ++y) {
                for (std::size_t x = lo[0]; x < hi[0]; ++x) {
                    m = std::min(m, f[(z * size[1] + y) * size[0] + x]);
                }
            }
        }
        least[part] = m;
    }
    return least;
}

}  // namespace voxfield
