// Process-wide settings of the long-running binaries (rve_server,
// mpm_client) and of the benchmarks that time them, kept in one place so that
// a benchmark runs as the binary it stands for. Tests keep the defaults.
#ifndef RVEHUB_RVE_SERVER_COMMON_PROCESS_H_
#define RVEHUB_RVE_SERVER_COMMON_PROCESS_H_

namespace rvehub {

// Call early in main(), before any thread starts.
// - Abseil's mutex deadlock detection off: Debian's Abseil is built with it
//   on, a graph update per lock, and the registry locks every RVE of a batch
//   every step (~2 % of footing-dense).
// - glibc's heap keeps freed memory for reuse: every MPM step allocates and
//   frees its batch's outcomes (about 1 KB per RVE, 0.6 MB for 600 RVEs).
//   By default glibc maps such blocks fresh from the kernel and hands them back
//   after the step, and every fresh page faults: footing-coarse took 340 000
//   page faults and 4.8 s of 17 s in its first 1200 steps, 24 000 and 0.7 s
//   with these settings. Blocks up to 32 MiB (glibc's own ceiling for
//   its adaptive threshold) come from the heap; up to 128 MiB of freed heap
//   stays with the process.
// - SIGXFSZ ignored: a file size limit (ulimit -f, a batch system's) then
//   makes the write that passes it fail with EFBIG, an error the writer
//   reports (the run record says "failed"), rather than killing the process.
void SetUpLongRunningProcess();

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_COMMON_PROCESS_H_
