// What bench/cl_overhead.c and bench/cl_launch_cost.c share: a monotonic clock in microseconds,
// a comparator for qsort of doubles, CHECK (an OpenCL error ends the program with status 1) and
// the device named by the first argument ("gpu", the default, or "cpu"; none: status 2).
#pragma once
#define CL_TARGET_OPENCL_VERSION 300
#include <CL/cl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_us(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e6 + t.tv_nsec * 1e-3;
}

static int cmp(const void* a, const void* b) {
    const double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

#define CHECK(e)                                                          \
    do {                                                                  \
        cl_int e_ = (e);                                                  \
        if (e_ != CL_SUCCESS) {                                           \
            fprintf(stderr, "OpenCL error %d at line %d\n", e_, __LINE__); \
            exit(1);                                                      \
        }                                                                 \
    } while (0)

static cl_device_id bench_device(int argc, char** argv) {
    const cl_device_type type =
        argc > 1 && strcmp(argv[1], "cpu") == 0 ? CL_DEVICE_TYPE_CPU : CL_DEVICE_TYPE_GPU;
    cl_platform_id platforms[8];
    cl_uint np = 0;
    CHECK(clGetPlatformIDs(8, platforms, &np));
    cl_device_id dev = NULL;
    for (cl_uint i = 0; i < np && !dev; ++i) {
        if (clGetDeviceIDs(platforms[i], type, 1, &dev, NULL) != CL_SUCCESS) dev = NULL;
    }
    if (!dev) {
        fprintf(stderr, "no %s device\n", type == CL_DEVICE_TYPE_GPU ? "GPU" : "CPU");
        exit(2);
    }
    return dev;
}
