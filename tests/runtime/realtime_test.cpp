#include "runtime/realtime.h"

#include <gtest/gtest.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <functional>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>

#include "runtime/sanitizers.h"

namespace rilo {
namespace {

std::string joined(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += l + "\n";
  return out;
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// Runs `body` in a forked child (process-wide changes such as mlockall,
// mallopt or dropping privileges must not leak into the test process) and
// returns its exit code and output.
struct ChildResult {
  int exit_code = -1;
  std::string output;
};
ChildResult runInChild(const std::function<std::string()>& body) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    int code = 0;
    std::string out;
    try {
      out = body();
    } catch (const std::exception& e) {
      out = std::string("exception: ") + e.what();
      code = 2;
    }
    std::size_t written = 0;
    while (written < out.size()) {
      const ssize_t n = write(fds[1], out.data() + written, out.size() - written);
      if (n <= 0) break;
      written += static_cast<std::size_t>(n);
    }
    close(fds[1]);
    _exit(code);
  }
  close(fds[1]);
  ChildResult result;
  char buf[4096];
  for (;;) {
    const ssize_t n = read(fds[0], buf, sizeof(buf));
    if (n <= 0) break;
    result.output.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// Leaves root (all capabilities) for nobody, with the given real-time limits.
std::string dropPrivileges(rlim_t rtprio, rlim_t memlock_bytes) {
  const rlimit rt{rtprio, rtprio};
  const rlimit mem{memlock_bytes, memlock_bytes};
  // Raising a hard limit needs CAP_SYS_RESOURCE, which containers often withhold.
  if (setrlimit(RLIMIT_RTPRIO, &rt) != 0) return "cannot set RLIMIT_RTPRIO";
  if (setrlimit(RLIMIT_MEMLOCK, &mem) != 0) return "cannot set RLIMIT_MEMLOCK";
  if (geteuid() == 0 && (setgid(65534) != 0 || setuid(65534) != 0)) return "setuid failed";
  return {};
}

std::string invalidArgumentMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return {};
}

TEST(Realtime, InvalidThreadSettingsThrowNamingTheField) {
  ThreadRealtimeSettings s;
  s.name = "estimator";
  for (int bad : {-1, 100, 1000}) {
    s.fifo_priority = bad;
    const std::string msg = invalidArgumentMessage([&] { applyThreadRealtime(pthread_self(), s); });
    EXPECT_TRUE(contains(msg, "fifo_priority")) << bad << ": " << msg;
    EXPECT_TRUE(contains(msg, "estimator")) << msg;
  }
  s.fifo_priority = 0;
  const long n_cpus = sysconf(_SC_NPROCESSORS_CONF);
  for (int bad : {-1, static_cast<int>(n_cpus), 100000}) {
    s.cpus = {0, bad};
    const std::string msg = invalidArgumentMessage([&] { applyThreadRealtime(pthread_self(), s); });
    EXPECT_TRUE(contains(msg, "cpus")) << bad << ": " << msg;
    EXPECT_TRUE(contains(msg, std::to_string(bad))) << msg;
  }
}

TEST(Realtime, StackPrefaultMustFitInTheStack) {
  EXPECT_NO_THROW(prefaultStack(128u << 10));
  EXPECT_NO_THROW(prefaultStack(0));
  EXPECT_TRUE(contains(invalidArgumentMessage([] { prefaultStack(std::size_t{1} << 40); }), "bytes"));
  ProcessRealtimeSettings p;
  p.lock_memory = false;
  p.heap_reserve_bytes = 0;
  p.stack_prefault_bytes = std::size_t{1} << 40;
  EXPECT_TRUE(contains(invalidArgumentMessage([&] { applyProcessRealtime(p); }), "stack_prefault_bytes"));
}

TEST(Realtime, ThreadGetsNameAffinityAndFifoPriority) {
  std::promise<void> release;
  std::thread worker([f = release.get_future()]() mutable { f.wait(); });
  ThreadRealtimeSettings s;
  s.name = "rilo-test-realtime-worker";  // longer than Linux keeps
  s.fifo_priority = 1;                    // lowest FIFO priority, and the thread only waits
  s.cpus = {0};
  const std::vector<std::string> warnings = applyThreadRealtime(worker, s);

  char name[32] = {};
  ASSERT_EQ(pthread_getname_np(worker.native_handle(), name, sizeof(name)), 0);
  EXPECT_STREQ(name, "rilo-test-realt");
  const std::string text = joined(warnings);
  if (contains(text, "SCHED_FIFO")) {
    // A CI container without CAP_SYS_NICE: the warning must say what grants it.
    EXPECT_TRUE(contains(text, "CAP_SYS_NICE")) << text;
  } else {
    int policy = 0;
    sched_param param{};
    ASSERT_EQ(pthread_getschedparam(worker.native_handle(), &policy, &param), 0);
    EXPECT_EQ(policy, SCHED_FIFO);
    EXPECT_EQ(param.sched_priority, 1);
  }
  if (!contains(text, "CPU affinity")) {
    cpu_set_t set;
    ASSERT_EQ(pthread_getaffinity_np(worker.native_handle(), sizeof(set), &set), 0);
    EXPECT_EQ(CPU_COUNT(&set), 1);
    EXPECT_TRUE(CPU_ISSET(0, &set));
  }
  release.set_value();
  worker.join();
}

TEST(Realtime, UnprivilegedSetUpWarnsAndContinues) {
  const ChildResult r = runInChild([] {
    const std::string dropped = dropPrivileges(0, 64u << 10);
    if (!dropped.empty()) return dropped;
    ProcessRealtimeSettings p;
    p.heap_reserve_bytes = 0;
    p.stack_prefault_bytes = 64u << 10;
    ThreadRealtimeSettings t;
    t.name = "estimator";
    t.fifo_priority = 80;
    return joined(applyProcessRealtime(p)) + joined(applyThreadRealtime(pthread_self(), t));
  });
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "SCHED_FIFO priority 80 for thread 'estimator' not permitted (EPERM")) << r.output;
  EXPECT_TRUE(contains(r.output, "grant CAP_SYS_NICE or LimitRTPRIO=80 in the unit")) << r.output;
  if (kSanitizerBuild) {
    EXPECT_TRUE(contains(r.output, "memory not locked: sanitizer build")) << r.output;
  } else {
    EXPECT_TRUE(contains(r.output, "memory not locked")) << r.output;
    EXPECT_TRUE(contains(r.output, "grant CAP_IPC_LOCK or set LimitMEMLOCK=infinity")) << r.output;
    EXPECT_TRUE(contains(r.output, "RLIMIT_MEMLOCK is 64 KiB")) << r.output;
  }
}

TEST(Realtime, PriorityIsClampedToRlimitRtprio) {
  const ChildResult r = runInChild([] {
    const std::string dropped = dropPrivileges(5, 64u << 10);
    if (!dropped.empty()) return dropped;
    ThreadRealtimeSettings t;
    t.name = "publisher";
    t.fifo_priority = 80;
    std::string out = joined(applyThreadRealtime(pthread_self(), t));
    int policy = 0;
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy, &param);
    return out + "policy " + std::to_string(policy) + " priority " + std::to_string(param.sched_priority) + "\n";
  });
  ASSERT_EQ(r.exit_code, 0) << r.output;
  if (contains(r.output, "cannot set RLIMIT_RTPRIO")) GTEST_SKIP() << "raising RLIMIT_RTPRIO needs CAP_SYS_RESOURCE";
  if (contains(r.output, "clamped")) {
    EXPECT_TRUE(contains(r.output, "SCHED_FIFO priority 80 for thread 'publisher' clamped to 5")) << r.output;
    EXPECT_TRUE(contains(r.output, "policy " + std::to_string(SCHED_FIFO) + " priority 5")) << r.output;
  } else {
    // The system refuses real-time scheduling altogether (container, RT group budget 0).
    EXPECT_TRUE(contains(r.output, "not permitted")) << r.output;
  }
}

TEST(Realtime, LocksMemoryAndKeepsTheHeapReserve) {
  if (kSanitizerBuild) GTEST_SKIP() << "mlockall would lock the sanitizer's shadow memory";
  constexpr std::size_t kReserve = 8u << 20;
  const ChildResult r = runInChild([] {
    ProcessRealtimeSettings p;
    p.heap_reserve_bytes = kReserve;
    p.stack_prefault_bytes = 256u << 10;
    std::string out = joined(applyProcessRealtime(p));
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);) {
      if (line.rfind("VmLck:", 0) == 0) out += line + "\n";
    }
    // Freed reserve stays with malloc (not trimmed back to the system).
    out += "free heap " + std::to_string(mallinfo2().fordblks) + "\n";
    return out;
  });
  ASSERT_EQ(r.exit_code, 0) << r.output;
  if (contains(r.output, "memory not locked")) {
    EXPECT_TRUE(contains(r.output, "CAP_IPC_LOCK")) << r.output;  // unprivileged CI
  } else {
    EXPECT_FALSE(contains(r.output, "VmLck:\t       0 kB")) << r.output;
    EXPECT_TRUE(contains(r.output, "VmLck:")) << r.output;
  }
  const auto pos = r.output.find("free heap ");
  ASSERT_NE(pos, std::string::npos) << r.output;
  EXPECT_GE(std::stoull(r.output.substr(pos + 10)), kReserve) << r.output;
}

TEST(Realtime, HeapAndStackSetUpWithoutLockingGivesNoWarnings) {
  const ChildResult r = runInChild([] {
    ProcessRealtimeSettings p;
    p.lock_memory = false;
    p.heap_reserve_bytes = 1u << 20;
    p.stack_prefault_bytes = 64u << 10;
    return joined(applyProcessRealtime(p));
  });
  ASSERT_EQ(r.exit_code, 0) << r.output;
  if (!kSanitizerBuild) {
    EXPECT_EQ(r.output, "");
  }
}

}  // namespace
}  // namespace rilo
