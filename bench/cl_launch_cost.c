// Host cost of a kernel launch by what it is given (issue 24: an edit is paced by its launches):
// 1, 4, 8 or 16 buffer arguments, 8 sub-buffers of one buffer, a by-value table of 640 bytes;
// each launched on an idle queue (the call timed alone, then the queue finished, as an edit's
// first launches are) and back to back. Then an edit-shaped sequence (two small table writes and
// six launches of 16, 16, 8, 4, 4 and 16 buffers, the last with an event, then one wait) against
// the same launches taking their tables by value (no writes), and against one write. Queue
// without profiling, as a lean edit's. Medians of 2001 calls or sequences, after 200 untimed.
//   gcc -O2 -o /tmp/cl_launch_cost bench/cl_launch_cost.c -lOpenCL && /tmp/cl_launch_cost [gpu|cpu]
#include "cl_bench.h"

#define N 2001
#define WARM 200
// bufN: N global buffers, the first written where a flag says (never); table: 80 longs by value.
static const char* kSource =
    "typedef struct { long v[80]; } Table;\n"
    "#define B(i) __global int* b##i\n"
    "__kernel void buf1(B(0), int f) { if (f < 0) b0[0] = f; }\n"
    "__kernel void buf4(B(0), B(1), B(2), B(3), int f) { if (f < 0) b0[0] = b1[0] + b2[0] + b3[0]; }\n"
    "__kernel void buf8(B(0), B(1), B(2), B(3), B(4), B(5), B(6), B(7), int f) {\n"
    "  if (f < 0) b0[0] = b1[0] + b2[0] + b3[0] + b4[0] + b5[0] + b6[0] + b7[0]; }\n"
    "__kernel void buf16(B(0), B(1), B(2), B(3), B(4), B(5), B(6), B(7), B(8), B(9), B(10),\n"
    "  B(11), B(12), B(13), B(14), B(15), int f) {\n"
    "  if (f < 0) b0[0] = b1[0] + b2[0] + b3[0] + b4[0] + b5[0] + b6[0] + b7[0] + b8[0] + b9[0]\n"
    "    + b10[0] + b11[0] + b12[0] + b13[0] + b14[0] + b15[0]; }\n"
    "__kernel void table(B(0), Table t, int f) { if (f < 0) b0[0] = (int)t.v[f & 63]; }\n";

static cl_context ctx;
static cl_command_queue q;
static cl_program prog;
static cl_mem bufs[16], parent, subs[8], tables[2], pinned;
static void* host;

static cl_kernel make(const char* name, int nbuf, const cl_mem* from) {
    cl_int e;
    cl_kernel k = clCreateKernel(prog, name, &e);
    CHECK(e);
    for (int i = 0; i < nbuf; ++i) CHECK(clSetKernelArg(k, i, sizeof(cl_mem), &from[i]));
    int flag = 1;
    CHECK(clSetKernelArg(k, nbuf, sizeof flag, &flag));
    return k;
}
static cl_kernel make_table(void) {
    cl_int e;
    cl_kernel k = clCreateKernel(prog, "table", &e);
    CHECK(e);
    long t[80] = {0};
    int flag = 1;
    CHECK(clSetKernelArg(k, 0, sizeof(cl_mem), &bufs[0]));
    CHECK(clSetKernelArg(k, 1, sizeof t, t));
    CHECK(clSetKernelArg(k, 2, sizeof flag, &flag));
    return k;
}
static void launch(cl_kernel k, cl_event* ev) {
    const size_t g = 64, l = 64;
    CHECK(clEnqueueNDRangeKernel(q, k, 1, NULL, &g, &l, 0, NULL, ev));
}
static void report(const char* what, double* t) {
    qsort(t, N, sizeof t[0], cmp);
    printf("%-58s median %7.2f us (p10 %.2f, p90 %.2f)\n", what, t[N / 2], t[N / 10],
           t[N * 9 / 10]);
}

// One launch timed alone on an idle queue, and back to back (mean of 20 in a row).
static void single(const char* what, cl_kernel k) {
    static double t[N];
    char label[128];
    for (int i = -WARM; i < N; ++i) {
        const double t0 = now_us();
        launch(k, NULL);
        const double dt = now_us() - t0;
        CHECK(clFinish(q));
        if (i >= 0) t[i] = dt;
    }
    snprintf(label, sizeof label, "%s, idle queue", what);
    report(label, t);
    for (int i = -WARM / 10; i < N; ++i) {
        const double t0 = now_us();
        for (int j = 0; j < 20; ++j) launch(k, NULL);
        const double dt = (now_us() - t0) / 20;
        CHECK(clFinish(q));
        if (i >= 0) t[i] = dt;
    }
    snprintf(label, sizeof label, "%s, back to back", what);
    report(label, t);
}

// writes: 0 (tables by value), 1 (one write before the first launch) or 2 (one before the first
// and one before the third launch).
static void sequence(const char* what, int writes, cl_kernel* ks) {
    static double t[N];
    for (int i = -WARM; i < N; ++i) {
        const double t0 = now_us();
        cl_event last;
        for (int j = 0; j < 6; ++j) {
            if ((j == 0 && writes >= 1) || (j == 2 && writes == 2)) {
                CHECK(clEnqueueWriteBuffer(q, tables[j == 2], CL_FALSE, 0, 640,
                                           (char*)host + (j == 2) * 1024, 0, NULL, NULL));
            }
            launch(ks[j], j == 5 ? &last : NULL);
            if (j == 1) CHECK(clFlush(q));
        }
        CHECK(clWaitForEvents(1, &last));
        CHECK(clReleaseEvent(last));
        if (i >= 0) t[i] = now_us() - t0;
    }
    report(what, t);
}

int main(int argc, char** argv) {
    cl_device_id dev = bench_device(argc, argv);
    char name[256];
    size_t param = 0;
    clGetDeviceInfo(dev, CL_DEVICE_NAME, sizeof name, name, NULL);
    clGetDeviceInfo(dev, CL_DEVICE_MAX_PARAMETER_SIZE, sizeof param, &param, NULL);
    printf("device: %s, max parameter size %zu bytes\n", name, param);
    cl_int e;
    ctx = clCreateContext(NULL, 1, &dev, NULL, NULL, &e);
    CHECK(e);
    q = clCreateCommandQueueWithProperties(ctx, dev, NULL, &e);
    CHECK(e);
    prog = clCreateProgramWithSource(ctx, 1, &kSource, NULL, &e);
    CHECK(e);
    CHECK(clBuildProgram(prog, 1, &dev, "", NULL, NULL));
    for (int i = 0; i < 16; ++i) {
        bufs[i] = clCreateBuffer(ctx, CL_MEM_READ_WRITE, 1 << 20, NULL, &e);
        CHECK(e);
    }
    parent = clCreateBuffer(ctx, CL_MEM_READ_ONLY, 8 * 4096, NULL, &e);
    CHECK(e);
    for (int i = 0; i < 8; ++i) {
        const cl_buffer_region r = {(size_t)i * 4096, 4096};
        subs[i] = clCreateSubBuffer(parent, CL_MEM_READ_ONLY, CL_BUFFER_CREATE_TYPE_REGION, &r, &e);
        CHECK(e);
    }
    for (int i = 0; i < 2; ++i) {
        tables[i] = clCreateBuffer(ctx, CL_MEM_READ_ONLY, 4096, NULL, &e);
        CHECK(e);
    }
    pinned = clCreateBuffer(ctx, CL_MEM_ALLOC_HOST_PTR | CL_MEM_READ_WRITE, 4096, NULL, &e);
    CHECK(e);
    host = clEnqueueMapBuffer(q, pinned, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, 4096, 0, NULL,
                              NULL, &e);
    CHECK(e);
    memset(host, 0, 4096);

    single("1 buffer", make("buf1", 1, bufs));
    single("4 buffers", make("buf4", 4, bufs));
    single("8 buffers", make("buf8", 8, bufs));
    single("16 buffers", make("buf16", 16, bufs));
    single("8 sub-buffers of one buffer", make("buf8", 8, subs));
    single("1 buffer and a 640-byte table by value", make_table());

    // The edit's shape: encode_count, encode_write (16 buffers), gather (9), two passes (4),
    // scatter_minima (14, event); tables in their own buffers or by value.
    cl_kernel edit[6] = {make("buf16", 16, bufs), make("buf16", 16, bufs), make("buf8", 8, bufs),
                         make("buf4", 4, bufs),   make("buf4", 4, bufs),   make("buf16", 16, bufs)};
    cl_kernel few[6] = {make_table(), make_table(), make_table(),
                        make("buf4", 4, bufs), make("buf4", 4, bufs), make_table()};
    sequence("edit: 2 writes + 6 launches (16,16,8,4,4,16 buffers) + wait", 2, edit);
    sequence("edit: 1 write + the same 6 launches + wait", 1, edit);
    sequence("edit: the same 6 launches, no writes + wait", 0, edit);
    sequence("edit: 6 launches of 1-4 buffers, tables by value + wait", 0, few);
    printf("device: %s\n", name);
    return 0;
}
