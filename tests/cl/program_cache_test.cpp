// The OpenCL program cache (ocl::Context::program) on PoCL: keyed by name, options and source,
// as runtime.hpp says, so that one name built from two sources gives two programs.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cl_test_util.hpp"

namespace voxfield {
namespace {

using test::pocl;

// The value kernel `k` of `program` writes into one int.
int run_value(const cl::Program& program) {
    cl::Buffer out(pocl().context(), CL_MEM_READ_WRITE, sizeof(cl_int));
    cl::Kernel k(program, "value");
    k.setArg(0, out);
    pocl().queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(1));
    cl_int v = 0;
    pocl().queue().enqueueReadBuffer(out, CL_TRUE, 0, sizeof v, &v);
    return v;
}

TEST(ProgramCache, OneNameFromTwoSourcesIsTwoPrograms) {
    const std::string a = "kernel void value(global int* out) { *out = 1; }";
    const std::string b = "kernel void value(global int* out) { *out = 2; }";
    const cl::Program pa = pocl().program("program_cache_test", {a}, "");
    const cl::Program pb = pocl().program("program_cache_test", {b}, "");
    EXPECT_EQ(run_value(pa), 1);
    EXPECT_EQ(run_value(pb), 2);
    // And the same source again is the cached program.
    EXPECT_EQ(pocl().program("program_cache_test", {a}, "")(), pa());
}

}  // namespace
}  // namespace voxfield
