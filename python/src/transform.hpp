#pragma once
// voxfield.distance_transform, voxfield.Field and the .vox functions of `voxfield._core`.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "common.hpp"
#include "voxfield/pipeline/scene.hpp"

namespace voxfield::python {

py::object distance_transform(const py::object& world, const std::string& metric, bool signed_field,
                              const py::object& sampling, bool return_indices,
                              const py::object& max_distance,
                              const std::optional<std::string>& format,
                              const std::string& algorithm, const py::object& device,
                              const py::object& out = py::none(),
                              const std::string& targets = "nonzero");

py::tuple load_vox(const std::filesystem::path& path);
void save_vox(const std::filesystem::path& path, const py::object& world,
              const py::object& palette);

// A world and its distance field kept on the device across edits, with undo / redo of whole
// edit calls and the falling-sand simulation: a front end over pipeline::Scene, as the
// command line's simulate and replay are. Belongs to the thread that made it: its calls
// release the GIL while the device works, so one Field must not be used by two threads at
// once.
class Field {
  public:
    Field(const py::object& world, const std::string& metric, const py::object& device,
          const std::string& algorithm, const std::optional<std::string>& format,
          const py::object& sampling, bool signed_field, const py::object& max_distance);

    py::dict edit(const std::string& op, const std::string& shape,
                  const std::vector<std::int64_t>& center, std::int64_t radius,
                  std::int64_t material);
    py::dict apply_edits(const std::string& text);
    // The newest edit call undone / the newest undone one redone; empty stats when there is
    // none (Scene::undo, Scene::redo).
    py::dict undo();
    py::dict redo();
    bool can_undo() const;
    bool can_redo() const;
    // `steps` steps of falling sand on the device, numbered on from the Field's previous
    // ones (Scene::step_sand), the field updated after each; the steps' summed stats.
    py::dict step_sand(std::int64_t steps, std::uint64_t seed, std::int64_t sand,
                       std::int64_t water);
    std::uint64_t sand_steps() const { return sand_steps_; }
    py::array distances();
    py::array world();

  private:
    py::dict apply(const std::vector<Brush>& batch);

    // Declared first so that the context outlives the field's buffers.
    std::shared_ptr<Device> device_;
    Format format_ = Format::u16;
    std::unique_ptr<pipeline::Scene> scene_;
    std::uint64_t sand_steps_ = 0;  // the number of the next falling-sand step
};

}  // namespace voxfield::python
