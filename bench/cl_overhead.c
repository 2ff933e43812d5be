// Host cost of the OpenCL calls an edit makes, per call, on one device: clSetKernelArg (a buffer,
// a scalar), clEnqueueNDRangeKernel of an empty kernel without and with an event (on a profiling
// queue, as voxfield's), clGetEventProfilingInfo, clReleaseEvent, and a whole batch of 10
// launches ended by one wait. Medians of 21 rounds of 2000 calls (rounds of 200 batches).
//   gcc -O2 -o /tmp/cl_overhead bench/cl_overhead.c -lOpenCL && /tmp/cl_overhead [gpu|cpu]
#include "cl_bench.h"

#define ROUNDS 21
#define CALLS 2000
static const char* kSource =
    "__kernel void empty(__global int* a, int b) { if (b < 0) a[get_global_id(0)] = b; }";

int main(int argc, char** argv) {
    cl_device_id dev = bench_device(argc, argv);
    char name[256];
    clGetDeviceInfo(dev, CL_DEVICE_NAME, sizeof name, name, NULL);
    cl_int e;
    cl_context ctx = clCreateContext(NULL, 1, &dev, NULL, NULL, &e);
    CHECK(e);
    cl_queue_properties props[] = {CL_QUEUE_PROPERTIES, CL_QUEUE_PROFILING_ENABLE, 0};
    cl_command_queue q = clCreateCommandQueueWithProperties(ctx, dev, props, &e);
    CHECK(e);
    cl_program p = clCreateProgramWithSource(ctx, 1, &kSource, NULL, &e);
    CHECK(e);
    CHECK(clBuildProgram(p, 1, &dev, "", NULL, NULL));
    cl_kernel k = clCreateKernel(p, "empty", &e);
    CHECK(e);
    cl_mem buf = clCreateBuffer(ctx, CL_MEM_READ_WRITE, 4096, NULL, &e);
    CHECK(e);
    int scalar = 1;
    CHECK(clSetKernelArg(k, 0, sizeof buf, &buf));
    CHECK(clSetKernelArg(k, 1, sizeof scalar, &scalar));
    const size_t global = 64, local = 64;
    static cl_event events[CALLS];
    const char* names[] = {"setArg buffer", "setArg scalar", "enqueue, no event",
                           "enqueue with event", "profiling info read", "event release",
                           "10 launches + wait"};
    double med[7];
    for (int m = 0; m < 7; ++m) {
        double per[ROUNDS];
        for (int r = 0; r < ROUNDS; ++r) {
            if (m == 4 || m == 5) {  // events to read or release, made untimed
                for (int i = 0; i < CALLS; ++i)
                    CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, &local, 0, NULL,
                                                 &events[i]));
                CHECK(clFinish(q));
            }
            const double t0 = now_us();
            int calls = CALLS;
            for (int i = 0; i < CALLS && m < 6; ++i) {
                cl_ulong v;
                switch (m) {
                    case 0: CHECK(clSetKernelArg(k, 0, sizeof buf, &buf)); break;
                    case 1: scalar = i + 1; CHECK(clSetKernelArg(k, 1, sizeof scalar, &scalar)); break;
                    case 2: CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, &local, 0, NULL, NULL)); break;
                    case 3: CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, &local, 0, NULL, &events[i])); break;
                    case 4: CHECK(clGetEventProfilingInfo(events[i], CL_PROFILING_COMMAND_END, sizeof v, &v, NULL)); break;
                    case 5: CHECK(clReleaseEvent(events[i])); break;
                }
            }
            if (m == 6) {
                calls = CALLS / 10;
                for (int b = 0; b < calls; ++b) {
                    cl_event last;
                    for (int i = 0; i < 9; ++i)
                        CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, &local, 0, NULL, NULL));
                    CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &global, &local, 0, NULL, &last));
                    CHECK(clWaitForEvents(1, &last));
                    CHECK(clReleaseEvent(last));
                }
            }
            per[r] = (now_us() - t0) / calls;
            if (m == 2 || m == 3) CHECK(clFinish(q));
            if (m == 3 || m == 4)
                for (int i = 0; i < CALLS; ++i) CHECK(clReleaseEvent(events[i]));
        }
        qsort(per, ROUNDS, sizeof per[0], cmp);
        med[m] = per[ROUNDS / 2];
        printf("%-22s median %8.3f us per call (min %.3f, max %.3f)\n", names[m], med[m], per[0],
               per[ROUNDS - 1]);
    }
    printf("device: %s\n", name);
    return 0;
}
