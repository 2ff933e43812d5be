#pragma once
// The dissertation's generators (brute force, FIM, JFA, their hybrids; chapter 4).
#include <memory>

#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

// The program of the dissertation's kernels (classic_common, brute, fim, jfa, monolithic)
// writing `format`, built once per context.
cl::Program classic_program(Context& ctx, Format format);

// options: resolved (resolve_options), algorithm other than exact.
std::unique_ptr<Generator> make_classic(Context& ctx, const World& world, const Palette& palette,
                                        const GeneratorOptions& options);

}  // namespace voxfield::ocl
