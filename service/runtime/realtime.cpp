#include "runtime/realtime.h"

#include <alloca.h>
#include <malloc.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "runtime/sanitizers.h"

namespace rilo {
namespace {

// Linux keeps 15 characters of a thread name (TASK_COMM_LEN 16 with the NUL).
constexpr std::size_t kMaxThreadName = 15;
// Stack left untouched by prefaultStack(): frames of the caller and of signal handlers.
constexpr std::size_t kStackMargin = 64u << 10;

/// "EPERM: Operation not permitted" (glibc >= 2.32: thread-safe, no buffer).
std::string errnoText(int err) {
  const char* name = strerrorname_np(err);
  const char* desc = strerrordesc_np(err);
  return std::string(name != nullptr ? name : "errno " + std::to_string(err)) + ": " +
         (desc != nullptr ? desc : "unknown error");
}

std::string limitText(rlim_t value) {
  return value == RLIM_INFINITY ? std::string("unlimited") : std::to_string(value / 1024) + " KiB";
}

std::string mib(std::size_t bytes) { return std::to_string(bytes >> 20) + " MiB"; }

std::string cpuList(const std::vector<int>& cpus) {
  std::string s = "{";
  for (std::size_t i = 0; i < cpus.size(); ++i) {
    if (i > 0) s += ',';
    s += std::to_string(cpus[i]);
  }
  s += '}';
  return s;
}

void lockMemory(std::vector<std::string>& warnings) {
  if (kSanitizerBuild) {
    warnings.push_back("memory not locked: sanitizer build (mlockall would try to lock the sanitizer's "
                       "terabytes of shadow memory)");
    return;
  }
  // Raise the limit first: without CAP_IPC_LOCK, mlockall fails (MCL_CURRENT)
  // or later allocations fail (MCL_FUTURE) beyond RLIMIT_MEMLOCK. Raising the
  // hard limit needs CAP_SYS_RESOURCE; otherwise take the soft limit to the hard one.
  rlimit limit{};
  getrlimit(RLIMIT_MEMLOCK, &limit);
  if (limit.rlim_cur != RLIM_INFINITY) {
    const rlimit unlimited{RLIM_INFINITY, RLIM_INFINITY};
    if (setrlimit(RLIMIT_MEMLOCK, &unlimited) == 0) {
      limit = unlimited;
    } else if (limit.rlim_cur < limit.rlim_max) {
      const rlimit to_hard{limit.rlim_max, limit.rlim_max};
      if (setrlimit(RLIMIT_MEMLOCK, &to_hard) == 0) limit = to_hard;
    }
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    const int err = errno;
    warnings.push_back("memory not locked: mlockall(MCL_CURRENT|MCL_FUTURE) failed (" + errnoText(err) +
                       "; RLIMIT_MEMLOCK is " + limitText(limit.rlim_cur) +
                       "): grant CAP_IPC_LOCK or set LimitMEMLOCK=infinity in the unit; "
                       "page faults may stall the real-time threads");
  }
}

void reserveHeap(std::size_t bytes, std::vector<std::string>& warnings) {
  // Freed memory stays in the process (no trim, no per-allocation mmap) and
  // all threads share the main arena, so the reserve below serves every thread.
  if (mallopt(M_MMAP_MAX, 0) != 1 || mallopt(M_TRIM_THRESHOLD, -1) != 1 || mallopt(M_ARENA_MAX, 1) != 1) {
    warnings.push_back("malloc tuning (mallopt M_MMAP_MAX/M_TRIM_THRESHOLD/M_ARENA_MAX) refused: freed heap "
                       "may return to the system and large allocations fault in fresh pages");
  }
  void* block = std::malloc(bytes);
  if (block == nullptr) {
    warnings.push_back("heap reserve of " + mib(bytes) + " not allocated (" + errnoText(ENOMEM) +
                       "): lower heap_reserve_bytes or raise the unit's MemoryMax=");
    return;
  }
  // Volatile stores: the compiler may not elide the touches (nor the malloc/free pair).
  auto* bytes_ptr = static_cast<volatile unsigned char*>(block);
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) bytes_ptr[i] = 0;
  std::free(block);
}

std::size_t currentStackSize() {
  pthread_attr_t attr;
  if (pthread_getattr_np(pthread_self(), &attr) != 0) return 0;
  std::size_t size = 0;
  pthread_attr_getstacksize(&attr, &size);
  pthread_attr_destroy(&attr);
  return size;
}

// Separate frame so the alloca'd block is released on return.
[[gnu::noinline]] void touchStack(std::size_t bytes) {
  auto* block = static_cast<volatile unsigned char*>(alloca(bytes));
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  // From the top (near the current frame) down: the stack grows downwards.
  for (std::size_t i = bytes; i > 0; i -= (i > page ? page : i)) block[i - 1] = 0;
  block[0] = 0;
}

void validate(const ThreadRealtimeSettings& s) {
  const std::string who = " (thread '" + s.name + "')";
  const int min_prio = sched_get_priority_min(SCHED_FIFO);
  const int max_prio = sched_get_priority_max(SCHED_FIFO);
  if (s.fifo_priority != 0 && (s.fifo_priority < min_prio || s.fifo_priority > max_prio)) {
    throw std::invalid_argument("ThreadRealtimeSettings.fifo_priority must be 0 (default scheduler) or in [" +
                                std::to_string(min_prio) + ", " + std::to_string(max_prio) + "], got " +
                                std::to_string(s.fifo_priority) + who);
  }
  const long n_cpus = sysconf(_SC_NPROCESSORS_CONF);
  for (const int cpu : s.cpus) {
    if (cpu < 0 || cpu >= n_cpus || cpu >= CPU_SETSIZE) {
      throw std::invalid_argument("ThreadRealtimeSettings.cpus: CPU index " + std::to_string(cpu) +
                                  " is not in [0, " + std::to_string(n_cpus) + ") on this machine" + who);
    }
  }
}

void setFifo(pthread_t thread, const ThreadRealtimeSettings& s, std::vector<std::string>& warnings) {
  sched_param param{};
  param.sched_priority = s.fifo_priority;
  int rc = pthread_setschedparam(thread, SCHED_FIFO, &param);
  if (rc == 0) return;
  const std::string what = "SCHED_FIFO priority " + std::to_string(s.fifo_priority) + " for thread '" + s.name + "'";
  if (rc != EPERM) {
    warnings.push_back(what + " not applied (" + errnoText(rc) + "); the thread keeps the default scheduler");
    return;
  }
  // Unprivileged: RLIMIT_RTPRIO is the highest priority allowed; clamp to it if it is above 0.
  rlimit rtprio{};
  getrlimit(RLIMIT_RTPRIO, &rtprio);
  const std::string hint = "grant CAP_SYS_NICE or LimitRTPRIO=" + std::to_string(s.fifo_priority) +
                           " in the unit (in a container, the runtime must allow real-time scheduling)";
  if (rtprio.rlim_cur > 0 && rtprio.rlim_cur < static_cast<rlim_t>(s.fifo_priority)) {
    param.sched_priority = static_cast<int>(rtprio.rlim_cur);
    rc = pthread_setschedparam(thread, SCHED_FIFO, &param);
    if (rc == 0) {
      warnings.push_back(what + " clamped to " + std::to_string(param.sched_priority) +
                         " (RLIMIT_RTPRIO): " + hint);
      return;
    }
  }
  warnings.push_back(what + " not permitted (" + errnoText(EPERM) + "; RLIMIT_RTPRIO is " +
                     std::to_string(rtprio.rlim_cur) + "): " + hint +
                     "; the thread keeps the default scheduler");
}

}  // namespace

std::vector<std::string> applyProcessRealtime(const ProcessRealtimeSettings& settings) {
  if (settings.stack_prefault_bytes > 0) {
    // Validate before changing anything.
    const std::size_t stack = currentStackSize();
    if (stack != 0 && settings.stack_prefault_bytes + kStackMargin > stack) {
      throw std::invalid_argument("ProcessRealtimeSettings.stack_prefault_bytes (" +
                                  std::to_string(settings.stack_prefault_bytes) + ") must leave 64 KiB of the " +
                                  std::to_string(stack) + "-byte stack");
    }
  }
  std::vector<std::string> warnings;
  if (settings.lock_memory) lockMemory(warnings);
  if (settings.heap_reserve_bytes > 0) reserveHeap(settings.heap_reserve_bytes, warnings);
  if (settings.stack_prefault_bytes > 0) touchStack(settings.stack_prefault_bytes);
  return warnings;
}

void prefaultStack(std::size_t bytes) {
  if (bytes == 0) return;
  const std::size_t stack = currentStackSize();
  if (stack != 0 && bytes + kStackMargin > stack) {
    throw std::invalid_argument("prefaultStack: bytes (" + std::to_string(bytes) + ") must leave 64 KiB of the " +
                                std::to_string(stack) + "-byte stack");
  }
  touchStack(bytes);
}

std::vector<std::string> applyThreadRealtime(pthread_t thread, const ThreadRealtimeSettings& settings) {
  validate(settings);
  std::vector<std::string> warnings;
  if (!settings.name.empty()) {
    const std::string name = settings.name.substr(0, kMaxThreadName);
    const int rc = pthread_setname_np(thread, name.c_str());
    if (rc != 0) warnings.push_back("thread name '" + name + "' not set (" + errnoText(rc) + ")");
  }
  if (!settings.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (const int cpu : settings.cpus) CPU_SET(static_cast<std::size_t>(cpu), &set);
    const int rc = pthread_setaffinity_np(thread, sizeof(set), &set);
    if (rc != 0) {
      warnings.push_back("CPU affinity " + cpuList(settings.cpus) + " for thread '" + settings.name +
                         "' not applied (" + errnoText(rc) +
                         "): the CPUs must be in the process's allowed set (taskset, cgroup cpuset, "
                         "CPUAffinity=/AllowedCPUs= in the unit)");
    }
  }
  if (settings.fifo_priority > 0) setFifo(thread, settings, warnings);
  return warnings;
}

std::vector<std::string> applyThreadRealtime(std::thread& thread, const ThreadRealtimeSettings& settings) {
  return applyThreadRealtime(thread.native_handle(), settings);
}

}  // namespace rilo
