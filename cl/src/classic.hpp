#pragma once
// The dissertation's generators (brute force, FIM, JFA, their hybrids; chapter 4).
#include <memory>

#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

// options: resolved (resolve_options), algorithm other than exact.
std::unique_ptr<Generator> make_classic(Context& ctx, const World& world, const Palette& palette,
                                        const GeneratorOptions& options);

}  // namespace voxfield::ocl
