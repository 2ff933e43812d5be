// OpenCL call trace (LD_PRELOAD shim): one line "@@CL <call> <blocking>" on stderr per enqueue,
// finish, flush and wait for events, kernels by name, in call order, for counting the commands
// and host waits of a run independently of its own accounting (bench/README.md, sparse edits).
//   gcc -O2 -shared -fPIC -o /tmp/cl_calls.so bench/cl_calls.c -ldl -lOpenCL
//   LD_PRELOAD=/tmp/cl_calls.so voxfield bench --suite sparse ... 2> calls.log
#define _GNU_SOURCE
#define CL_TARGET_OPENCL_VERSION 300
#include <CL/cl.h>
#include <dlfcn.h>
#include <stdio.h>
#include <unistd.h>
static void note(const char* name, int blocking) {
    char buf[128];
    int n = snprintf(buf, sizeof buf, "@@CL %s %d\n", name, blocking);
    write(2, buf, n);
}
#define REAL(name)                 \
    static __typeof__(&name) real; \
    if (!real)                     \
    real = (__typeof__(&name))dlsym(RTLD_NEXT, #name)
cl_int clEnqueueNDRangeKernel(cl_command_queue q, cl_kernel k, cl_uint d, const size_t* o,
                              const size_t* g, const size_t* l, cl_uint n, const cl_event* w,
                              cl_event* e) {
    REAL(clEnqueueNDRangeKernel);
    char name[96] = "kernel:";
    clGetKernelInfo(k, CL_KERNEL_FUNCTION_NAME, sizeof name - 8, name + 7, NULL);
    note(name, 0);
    return real(q, k, d, o, g, l, n, w, e);
}
cl_int clEnqueueWriteBuffer(cl_command_queue q, cl_mem b, cl_bool bl, size_t off, size_t sz,
                            const void* p, cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueWriteBuffer);
    note("write", bl);
    return real(q, b, bl, off, sz, p, n, w, e);
}
cl_int clEnqueueReadBuffer(cl_command_queue q, cl_mem b, cl_bool bl, size_t off, size_t sz, void* p,
                           cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueReadBuffer);
    note("read", bl);
    return real(q, b, bl, off, sz, p, n, w, e);
}
cl_int clEnqueueCopyBuffer(cl_command_queue q, cl_mem a, cl_mem b, size_t x, size_t y, size_t z,
                           cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueCopyBuffer);
    note("copy", 0);
    return real(q, a, b, x, y, z, n, w, e);
}
cl_int clEnqueueFillBuffer(cl_command_queue q, cl_mem b, const void* p, size_t ps, size_t off,
                           size_t sz, cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueFillBuffer);
    note("fill", 0);
    return real(q, b, p, ps, off, sz, n, w, e);
}
void* clEnqueueMapBuffer(cl_command_queue q, cl_mem b, cl_bool bl, cl_map_flags f, size_t off,
                         size_t sz, cl_uint n, const cl_event* w, cl_event* e, cl_int* err) {
    REAL(clEnqueueMapBuffer);
    note("map", bl);
    return real(q, b, bl, f, off, sz, n, w, e, err);
}
cl_int clEnqueueUnmapMemObject(cl_command_queue q, cl_mem b, void* p, cl_uint n, const cl_event* w,
                               cl_event* e) {
    REAL(clEnqueueUnmapMemObject);
    note("unmap", 0);
    return real(q, b, p, n, w, e);
}
cl_int clFinish(cl_command_queue q) {
    REAL(clFinish);
    note("finish", 1);
    return real(q);
}
cl_int clWaitForEvents(cl_uint n, const cl_event* l) {
    REAL(clWaitForEvents);
    note("waitevents", 1);
    return real(n, l);
}
cl_int clFlush(cl_command_queue q) {
    REAL(clFlush);
    note("flush", 0);
    return real(q);
}
