#pragma once
// `voxfield view` on sparse worlds (core/sparse.hpp: a tile grid of 64-trees): the world and its
// exact bounded field on the OpenCL device (ocl::SparseField), traced through its 64-trees by
// vk::SparseTracer (flat or lit), frames read back and presented through the host. The brush
// edits the device's world (SparseField::apply_brush: the field updated within D of the edit).
// Where the devices share memory (pipeline::SharedTrees) the tracer reads OpenCL's trees in place
// and is only told where edited tiles now lie; aiming and the benchmark's surface points read
// the device's voxels (SparseDeviceWorld::pick, voxels), so nothing moves through the host but
// the overlay's world figures (read at most twice a second). Otherwise (path 3) the edited tiles
// are read back (SparseField::world) and written into the tracer's edit arena
// (SparseTracer::update_tiles), never the whole world. `--benchmark` runs the editing protocol
// headless as on dense worlds and reports frame, edit and tile-update times. A generated city
// (`--scene city`) is built tile by tile: no dense array of the world exists at any point.
#include <memory>

#include "view_options.hpp"
#include "view_window.hpp"
#include "voxfield/vk/context.hpp"

namespace voxfield::cli {

// Whether `view` shows the world sparse: --sparse, an INPUT that `render` takes sparse
// (generate_sparse.hpp's needs_sparse), or a generated world over kSparseAutoVoxels voxels.
bool view_goes_sparse(const ViewCliOptions& o);

// The viewer's loop on a sparse world; `window` is open or the caller chose to run headless.
// With --simulate, falling sand and water (ocl::SparseSand, colours 2 and 3 as on dense worlds)
// steps every frame unless paused (G; N steps once), the tracer told of the stepped tiles as of
// an edit's. Ctrl+Z / Ctrl+Y undo and redo strokes from a history on the OpenCL device
// (sparse_history.hpp). Ctrl+S, the script's `save STEM` and --world-output W.vdb write the world
// and its field as .vdb grids. InputError (exit 2) for what sparse worlds do not take:
// --field-output, a --world-output other than .vdb, --present gpu, parts (.sdf.json, mixed scenes),
// generated scenes other than city beyond one dense array, and the script's algorithm, metric and
// scene selections and check.
int run_view_sparse(ViewCliOptions& o, const ViewInputs& in, Window& window,
                    const std::shared_ptr<vk::ValidationLog>& validation);

}  // namespace voxfield::cli
