#pragma once
// Real-time set-up of the service, in the order that makes it hold:
//   process: raise RLIMIT_MEMLOCK, mlockall(MCL_CURRENT | MCL_FUTURE), keep
//            freed heap in the process and pre-fault a heap reserve, pre-fault
//            the calling thread's stack;
//   threads: name, SCHED_FIFO priority, CPU affinity, each promoted on its own
//            (never the whole process).
// Missing privileges are not errors: each step that the system refuses yields
// a warning naming what is missing and what grants it, and set-up continues
// (the service runs degraded, with page faults and normal scheduling
// possible). Invalid settings throw std::invalid_argument naming the field.
#include <pthread.h>

#include <cstddef>
#include <string>
#include <thread>
#include <vector>

namespace rilo {

struct ProcessRealtimeSettings {
  /// Raise RLIMIT_MEMLOCK and lock all current and future pages (no page faults
  /// to disk or from reclaim). Without CAP_IPC_LOCK, RLIMIT_MEMLOCK is then the
  /// process's memory budget: allocations beyond it fail. Skipped with a
  /// warning in sanitizer builds.
  bool lock_memory = true;
  /// Bytes of heap allocated, touched and freed at start-up; malloc is told
  /// to keep freed memory (no trimming, no mmap, one arena) so later
  /// allocations up to this size reuse resident, locked pages. 0 = skip.
  std::size_t heap_reserve_bytes = 32u << 20;
  /// Bytes of the calling thread's stack touched now (0 = skip); must fit in its stack.
  std::size_t stack_prefault_bytes = 256u << 10;
};

struct ThreadRealtimeSettings {
  /// Thread name shown by ps/top/perf (Linux keeps 15 characters) and used in
  /// warnings. Empty: keep the name.
  std::string name;
  /// SCHED_FIFO priority 1..99 (see sched(7)); 0 keeps the default scheduler.
  int fifo_priority = 0;
  /// CPU indices (0-based) the thread may run on; empty keeps the inherited set.
  std::vector<int> cpus;
};

/// Applies the process settings. Call it first in main(), before any thread
/// starts (the malloc settings do not reach arenas that threads already made).
/// Returns the warnings (empty if all applied). Throws std::invalid_argument
/// if stack_prefault_bytes exceeds the stack.
std::vector<std::string> applyProcessRealtime(const ProcessRealtimeSettings& settings);

/// Applies the settings to `thread` (may be pthread_self()). Returns the
/// warnings. Throws std::invalid_argument if fifo_priority is not 0 or in
/// [1, 99], or a CPU index is negative or not below the number of CPUs.
std::vector<std::string> applyThreadRealtime(pthread_t thread, const ThreadRealtimeSettings& settings);
std::vector<std::string> applyThreadRealtime(std::thread& thread, const ThreadRealtimeSettings& settings);

/// Touches `bytes` of the calling thread's stack so its pages are resident
/// (and locked, after mlockall) before the real-time loop starts. Each real-time
/// thread calls it first. Throws std::invalid_argument if it would not fit in
/// the stack (with a 64 KiB margin).
void prefaultStack(std::size_t bytes);

}  // namespace rilo
