#pragma once
// The process's resident memory as the benchmarks record it (`bench --suite sparse` and its
// OpenVDB peer, bench/sparse_bench).

namespace voxfield::bench {

// Resident memory now (bytes, /proc/self/statm).
double rss_now_bytes();
// The peak resident memory (bytes): since the last reset_peak_rss(), else since the process
// started (/proc/self/status's VmHWM; getrusage where that is unreadable).
double peak_rss_bytes();
// Resets the peak to the resident memory now (Linux: "5" to /proc/self/clear_refs), so that a
// later peak_rss_bytes() is the work's since; false where it could not.
bool reset_peak_rss();

}  // namespace voxfield::bench
