// voxfield.load_vox / voxfield.save_vox: MagicaVoxel files as numpy arrays.
#include <cstring>

#include "transform.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::python {

namespace {

py::array world_to_numpy(const World& world) {
    const Dims d = world.dims();
    py::array_t<std::uint8_t> out(std::vector<py::ssize_t>{d.z, d.y, d.x});
    std::memcpy(out.mutable_data(), world.voxels().data(), world.size());
    return out;
}

// palette: None (MagicaVoxel's default) or an integer array of shape (256, 4), values 0..255.
Palette palette_of(const py::object& palette) {
    Palette out;
    if (palette.is_none()) {
        return out;
    }
    const py::array a = py::module_::import("numpy").attr("asarray")(palette);
    if (a.ndim() != 2 || a.shape(0) != 256 || a.shape(1) != 4) {
        throw py::value_error("palette must have shape (256, 4) (RGBA per palette index), got " +
                              shape_text(a));
    }
    const char kind = kind_of(a.dtype());
    if (kind != 'u' && kind != 'i') {
        throw py::type_error("palette dtype " + dtype_name(a.dtype()) +
                             " is not supported: expected an integer type (uint8)");
    }
    const auto v = py::array_t<std::int64_t, py::array::forcecast>::ensure(a);
    const auto u = v.unchecked<2>();
    for (py::ssize_t i = 0; i < 256; ++i) {
        std::uint8_t rgba[4];
        for (py::ssize_t c = 0; c < 4; ++c) {
            if (u(i, c) < 0 || u(i, c) > 255) {
                throw py::value_error("palette value " + std::to_string(u(i, c)) + " at [" +
                                      std::to_string(i) + ", " + std::to_string(c) +
                                      "] is outside 0..255");
            }
            rgba[c] = static_cast<std::uint8_t>(u(i, c));
        }
        out[static_cast<std::uint8_t>(i)] = {rgba[0], rgba[1], rgba[2], rgba[3]};
    }
    return out;
}

}  // namespace

py::tuple load_vox(const std::filesystem::path& path) {
    std::optional<VoxModel> model;
    {
        py::gil_scoped_release release;
        model = read_vox(path);
    }
    py::array_t<std::uint8_t> palette(std::vector<py::ssize_t>{256, 4});
    auto p = palette.mutable_unchecked<2>();
    for (int i = 0; i < 256; ++i) {
        const Rgba& c = model->palette[static_cast<std::uint8_t>(i)];
        p(i, 0) = c.r;
        p(i, 1) = c.g;
        p(i, 2) = c.b;
        p(i, 3) = c.a;
    }
    return py::make_tuple(world_to_numpy(model->world), palette);
}

void save_vox(const std::filesystem::path& path, const py::object& world,
              const py::object& palette) {
    const WorldArray w = world_array(world);
    const Palette colours = palette_of(palette);
    py::gil_scoped_release release;
    write_vox(path, make_world(w, Labels::palette), colours);
}

}  // namespace voxfield::python
