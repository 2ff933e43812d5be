// OpenCL host-cost trace (LD_PRELOAD shim): one line "@@T <call> <start_ns> <ns>" on stderr per
// call of the functions below (kernels by name; transfers marked +event where they return one,
// +blocking where they block), with the host time the real call took, to count an operation's
// commands and host waits and say where its host time goes (bench/README.md, sparse edits).
// Lines are written after the call, outside the timed span.
//   gcc -O2 -shared -fPIC -o /tmp/cl_time.so bench/cl_time.c -ldl -lOpenCL
//   LD_PRELOAD=/tmp/cl_time.so voxfield bench --suite sparse ... 2> time.log
//   python3 bench/cl_time.py time.log
#define _GNU_SOURCE
#define CL_TARGET_OPENCL_VERSION 300
#include <CL/cl.h>
#include <dlfcn.h>
#include <stdio.h>
#include <time.h>
#include <unistd.h>
static long long now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1000000000LL + t.tv_nsec;
}
static void note(const char* name, long long t0, long long t1) {
    char buf[160];
    int n = snprintf(buf, sizeof buf, "@@T %s %lld %lld\n", name, t0, t1 - t0);
    write(2, buf, n);
}
// "base", "base+event", "base+blocking" or "base+event+blocking" into buf.
static const char* transfer(char* buf, size_t size, const char* base, const cl_event* e,
                            cl_bool blocking) {
    snprintf(buf, size, "%s%s%s", base, e ? "+event" : "", blocking ? "+blocking" : "");
    return buf;
}
#define REAL(name)                 \
    static __typeof__(&name) real; \
    if (!real)                     \
    real = (__typeof__(&name))dlsym(RTLD_NEXT, #name)
#define TIMED(label, call)     \
    long long t0 = now_ns();   \
    __typeof__(call) r = call; \
    note(label, t0, now_ns()); \
    return r
cl_int clEnqueueNDRangeKernel(cl_command_queue q, cl_kernel k, cl_uint d, const size_t* o,
                              const size_t* g, const size_t* l, cl_uint n, const cl_event* w,
                              cl_event* e) {
    REAL(clEnqueueNDRangeKernel);
    char name[96] = "kernel:";
    clGetKernelInfo(k, CL_KERNEL_FUNCTION_NAME, sizeof name - 8, name + 7, NULL);
    TIMED(name, real(q, k, d, o, g, l, n, w, e));
}
cl_int clEnqueueWriteBuffer(cl_command_queue q, cl_mem b, cl_bool bl, size_t off, size_t sz,
                            const void* p, cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueWriteBuffer);
    char label[32];
    TIMED(transfer(label, sizeof label, "write", e, bl), real(q, b, bl, off, sz, p, n, w, e));
}
cl_int clEnqueueReadBuffer(cl_command_queue q, cl_mem b, cl_bool bl, size_t off, size_t sz, void* p,
                           cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueReadBuffer);
    char label[32];
    TIMED(transfer(label, sizeof label, "read", e, bl), real(q, b, bl, off, sz, p, n, w, e));
}
cl_int clSetKernelArg(cl_kernel k, cl_uint i, size_t sz, const void* v) {
    REAL(clSetKernelArg);
    TIMED("setarg", real(k, i, sz, v));
}
cl_int clFlush(cl_command_queue q) {
    REAL(clFlush);
    TIMED("flush", real(q));
}
cl_int clFinish(cl_command_queue q) {
    REAL(clFinish);
    TIMED("finish", real(q));
}
cl_int clWaitForEvents(cl_uint n, const cl_event* l) {
    REAL(clWaitForEvents);
    TIMED("waitevents", real(n, l));
}
cl_int clGetEventInfo(cl_event e, cl_event_info p, size_t sz, void* v, size_t* r_sz) {
    REAL(clGetEventInfo);
    TIMED("eventinfo", real(e, p, sz, v, r_sz));
}
cl_int clGetEventProfilingInfo(cl_event e, cl_profiling_info p, size_t sz, void* v, size_t* r_sz) {
    REAL(clGetEventProfilingInfo);
    TIMED("profilinginfo", real(e, p, sz, v, r_sz));
}
cl_int clReleaseEvent(cl_event e) {
    REAL(clReleaseEvent);
    TIMED("releaseevent", real(e));
}
cl_int clRetainEvent(cl_event e) {
    REAL(clRetainEvent);
    TIMED("retainevent", real(e));
}
cl_int clRetainMemObject(cl_mem m) {
    REAL(clRetainMemObject);
    TIMED("retainmem", real(m));
}
cl_int clReleaseMemObject(cl_mem m) {
    REAL(clReleaseMemObject);
    TIMED("releasemem", real(m));
}
cl_int clRetainKernel(cl_kernel k) {
    REAL(clRetainKernel);
    TIMED("retainkernel", real(k));
}
cl_int clReleaseKernel(cl_kernel k) {
    REAL(clReleaseKernel);
    TIMED("releasekernel", real(k));
}
cl_mem clCreateBuffer(cl_context c, cl_mem_flags f, size_t sz, void* p, cl_int* err) {
    REAL(clCreateBuffer);
    TIMED("createbuffer", real(c, f, sz, p, err));
}
cl_kernel clCreateKernel(cl_program p, const char* name, cl_int* err) {
    REAL(clCreateKernel);
    TIMED("createkernel", real(p, name, err));
}
cl_int clBuildProgram(cl_program p, cl_uint n, const cl_device_id* d, const char* o,
                      void(CL_CALLBACK* f)(cl_program, void*), void* u) {
    REAL(clBuildProgram);
    TIMED("buildprogram", real(p, n, d, o, f, u));
}
void* clEnqueueMapBuffer(cl_command_queue q, cl_mem b, cl_bool bl, cl_map_flags f, size_t off,
                         size_t sz, cl_uint n, const cl_event* w, cl_event* e, cl_int* err) {
    REAL(clEnqueueMapBuffer);
    char label[32];
    TIMED(transfer(label, sizeof label, "map", e, bl), real(q, b, bl, f, off, sz, n, w, e, err));
}
cl_int clEnqueueCopyBuffer(cl_command_queue q, cl_mem a, cl_mem b, size_t x, size_t y, size_t z,
                           cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueCopyBuffer);
    char label[32];
    TIMED(transfer(label, sizeof label, "copy", e, CL_FALSE), real(q, a, b, x, y, z, n, w, e));
}
cl_int clEnqueueFillBuffer(cl_command_queue q, cl_mem b, const void* p, size_t ps, size_t off,
                           size_t sz, cl_uint n, const cl_event* w, cl_event* e) {
    REAL(clEnqueueFillBuffer);
    char label[32];
    TIMED(transfer(label, sizeof label, "fill", e, CL_FALSE), real(q, b, p, ps, off, sz, n, w, e));
}
cl_int clEnqueueUnmapMemObject(cl_command_queue q, cl_mem b, void* p, cl_uint n, const cl_event* w,
                               cl_event* e) {
    REAL(clEnqueueUnmapMemObject);
    char label[32];
    TIMED(transfer(label, sizeof label, "unmap", e, CL_FALSE), real(q, b, p, n, w, e));
}
