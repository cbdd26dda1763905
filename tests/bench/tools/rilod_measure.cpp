// rilod-measure: runs the real rilod (beside this binary) on a recording
// replayed in real time as if it came from the sensors, subscribes to its
// odometry over loopback DDS from this separate process, and reports
//  - IMU sample to DDS receive latency: CLOCK_MONOTONIC when this process
//    takes an odometry message minus its stamp, which is the IMU sample's time
//    (replay with shift_to_now: a sample is stamped with the time it is due
//    and pushed when the clock reaches it, like a driver reading its FIFO);
//    p50/p90/p99/p99.9/max over the tracking phase (first seconds skipped);
//  - the service's own odometry_latency_ms (sample in -> DDS write, worst per
//    status period);
//  - CPU use of rilod: whole process (wait4 rusage) and per thread
//    (/proc/<pid>/task/<tid>/stat, utime + stime) over the tracking phase, with
//    the per-IMU-sample cost of the source and publisher threads;
//  - the estimator budget from rilod's last status: smoother update mean, p99
//    and max, and the queues' high-water marks (how far each consumer fell behind).
// A measuring tool, not a test: figures depend on the machine and its load.
//
// Measured on the shared 2-core x86-64 development machine (load average
// 5-6 from other builds), office-demo (800 Hz IMU, 40 Hz ranging), x1,
// rilod's real-time settings (root: SCHED_FIFO 80 replay, 70 publisher):
//   receiver SCHED_FIFO 60:  p50 0.14 ms, p90 0.18, p99 0.28, p99.9 0.65, max 2.2 ms;
//   receiver normal:         p50 0.14 ms, p99 150 ms, max 317 ms (the loaded
//                            machine starves the receiving process, not rilod:
//                            in-service max 7.7 ms);
//   CPU while tracking 20.7 % of one core: estimator 13.1 %, publisher 5.3 %
//   (2.2 % while initializing: the wake-ups alone), replay source 2.2 %.
//   Before the publisher slept on WakeSignal (polling every 200 us):
//   p50 0.24 ms, p99 0.44 ms, max 5.4 ms; publisher 10.4 %, total 26.1 %.
//
//   rilod-measure [--recording DIR] [--speed 1] [--skip 3] [--no-realtime]
#include <CLI/CLI.hpp>

#include <dirent.h>
#include <sched.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.h"
#include "dds/subscriber.h"
#include "hal/bus/clock.h"
#include "hal/recording/recording_reader.h"
#include "support/source_tree.h"

namespace {

struct ThreadCpu {
  std::string name;
  long ticks = 0;  // utime + stime
};

/// utime + stime of every thread of `pid`, by tid.
std::map<int, ThreadCpu> threadCpu(pid_t pid) {
  std::map<int, ThreadCpu> out;
  const std::string dir = "/proc/" + std::to_string(pid) + "/task";
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return out;
  while (const dirent* e = ::readdir(d)) {
    if (e->d_name[0] == '.') continue;
    std::ifstream in(dir + "/" + e->d_name + "/stat");
    std::string line;
    if (!std::getline(in, line)) continue;
    const auto open = line.find('('), close = line.rfind(')');
    if (open == std::string::npos || close == std::string::npos) continue;
    ThreadCpu t;
    t.name = line.substr(open + 1, close - open - 1);
    std::istringstream rest(line.substr(close + 2));
    std::string field;
    long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && (rest >> field); ++i) {  // fields 14, 15 (1-based) are utime, stime
      if (i == 14) utime = std::stol(field);
      if (i == 15) stime = std::stol(field);
    }
    t.ticks = utime + stime;
    out[std::atoi(e->d_name)] = t;
  }
  ::closedir(d);
  return out;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::min<double>(static_cast<double>(v.size() - 1), p * static_cast<double>(v.size())));
  return v[i];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rilod-measure: latency IMU sample -> DDS receive and CPU use of rilod in real time"};
  std::string recording = (rilo::testing::sourceDir() / "tests" / "data" / "office-demo").string();
  double speed = 1.0, skip_s = 3.0;
  bool no_realtime = false;
  int receiver_priority = 0;
  std::uint32_t domain = 232;
  app.add_option("--recording", recording, "Recording folder")->check(CLI::ExistingDirectory)->capture_default_str();
  app.add_option("--speed", speed, "Replay speed (1 = real time)")->capture_default_str();
  app.add_option("--skip", skip_s, "Seconds of tracking skipped before measuring (warm-up)")->capture_default_str();
  app.add_option("--domain", domain, "DDS domain (loopback)")->capture_default_str();
  app.add_flag("--no-realtime", no_realtime, "Run rilod without SCHED_FIFO priorities and memory locking");
  app.add_option("--receiver-priority", receiver_priority,
                 "SCHED_FIFO priority of this receiving process (0: normal scheduling, like most subscribers)")
      ->check(CLI::Range(0, 99));
  CLI11_PARSE(app, argc, argv);
  recording = std::filesystem::absolute(recording).lexically_normal().string();  // the config lives elsewhere

  const rilo::Recording rec = rilo::readRecording(recording);
  const rilo::Vec3 lever = rec.meta.uwbLeverArm();
  char dir_template[] = "/tmp/rilod-measure-XXXXXX";
  const std::string dir = ::mkdtemp(dir_template);
  const std::string config = dir + "/rilod.yaml";
  {
    std::ofstream out(config);
    out << "sources:\n  mode: replay\n  replay:\n    path: " << recording << "\n    pace: real_time\n    speed: " << speed
        << "\n    shift_to_now: true\n"
        << "anchors:\n  file: " << recording << "/anchors.csv\n"
        << "estimator:\n  smoother: d-isam2\n  range:\n    lever_arm_m: [" << lever.x() << ", " << lever.y() << ", "
        << lever.z() << "]\n"
        << "dds:\n  domain: " << domain << "\n  loopback_only: true\n  stamp_clock: monotonic\n";
    if (no_realtime) {
      out << "realtime:\n  lock_memory: false\n  threads:\n    replay_source: {priority: 0}\n    publisher: {priority: 0}\n";
    }
  }

  if (receiver_priority > 0) {
    sched_param sp{};
    sp.sched_priority = receiver_priority;
    if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0) std::perror("rilod-measure: SCHED_FIFO for the receiver");
  }
  rilo::dds::ParticipantOptions po;
  po.domain_id = domain;
  po.config_xml = rilo::dds::loopbackConfigXml();
  rilo::dds::Participant participant(po);
  rilo::dds::SubscriberOptions so;
  so.pose = false;
  so.odometry_depth = 4096;
  rilo::dds::Subscriber subscriber(participant, so);

  const std::string rilod = (rilo::testing::binaryDir() / "rilod").string();
  const std::string log = dir + "/rilod.log";
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, STDOUT_FILENO);
      ::dup2(fd, STDERR_FILENO);
    }
    ::execl(rilod.c_str(), rilod.c_str(), "--config", config.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::printf("rilod (pid %d) replaying %s at x%g, %s; receiver %s; log %s\n", pid, recording.c_str(), speed,
              no_realtime ? "no real-time settings" : "rilod's real-time settings (SCHED_FIFO 80/70, mlockall)",
              receiver_priority > 0 ? ("SCHED_FIFO " + std::to_string(receiver_priority)).c_str() : "normal scheduling",
              log.c_str());

  std::vector<double> latency_ms;
  std::vector<rilo::dds::OdometryMessage> odometry;
  std::vector<rilo::dds::StatusMessage> status;
  rilo::ServiceStatus last{}, at_start{}, at_end{};
  std::int64_t tracking_since_ns = 0, window_start_ns = 0, window_end_ns = 0;
  std::map<int, ThreadCpu> cpu_start, cpu_end, init_cpu_start, init_cpu_end;
  std::int64_t init_start_ns = 0, init_end_ns = 0, last_cpu_read_ns = 0;
  double service_latency_max_ms = 0.0;
  std::vector<double> service_latency_ms;
  std::uint64_t received = 0;
  int exit_code = -1;
  rusage usage{};
  const auto t0 = std::chrono::steady_clock::now();
  for (;;) {
    subscriber.waitForData(std::chrono::milliseconds(50));
    odometry.clear();
    subscriber.takeOdometry(odometry);
    const std::int64_t now = rilo::hal::monotonicNowNs();
    const bool measuring = window_start_ns > 0;
    for (const auto& o : odometry) {
      ++received;
      if (measuring) latency_ms.push_back(static_cast<double>(now - o.stamp_ns) * 1e-6);
    }
    status.clear();
    subscriber.takeStatus(status);
    for (const auto& s : status) {
      last = s.status;
      if (last.state == rilo::TrackingState::kTracking && tracking_since_ns == 0) tracking_since_ns = now;
      if (measuring && last.odometry_latency_ms > 0.0) {
        service_latency_ms.push_back(last.odometry_latency_ms);
        service_latency_max_ms = std::max(service_latency_max_ms, last.odometry_latency_ms);
      }
    }
    // /proc is read twice a second (reading it at every message would make
    // this receiver the bottleneck of the latency it measures).
    const bool sample_cpu = now - last_cpu_read_ns >= 500'000'000;
    if (sample_cpu) last_cpu_read_ns = now;
    // Before tracking: the same threads idle-polling (no odometry is
    // published), the baseline of the per-thread figures.
    if (!sample_cpu) {
    } else if (init_start_ns == 0) {
      init_cpu_start = threadCpu(pid);
      if (init_cpu_start.size() > 3) init_start_ns = now;
    } else if (tracking_since_ns == 0) {
      for (const auto& [tid, t] : threadCpu(pid)) init_cpu_end[tid] = t;
      init_end_ns = now;
    }
    if (!measuring && tracking_since_ns > 0 && now - tracking_since_ns > static_cast<std::int64_t>(skip_s * 1e9)) {
      window_start_ns = now;
      at_start = last;
      cpu_start = threadCpu(pid);
    }
    if (measuring && sample_cpu) {
      // Per thread, the last values seen: threads end one by one at shutdown.
      const auto cpu = threadCpu(pid);
      for (const auto& [tid, t] : cpu) cpu_end[tid] = t;
      if (!cpu.empty() && last.state == rilo::TrackingState::kTracking) {
        window_end_ns = now;
        at_end = last;
      }
    }
    int st = 0;
    if (::wait4(pid, &st, WNOHANG, &usage) == pid) {
      exit_code = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      break;
    }
    if (std::chrono::steady_clock::now() - t0 > std::chrono::minutes(30)) {
      ::kill(pid, SIGTERM);
    }
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double window_s = static_cast<double>(window_end_ns - window_start_ns) * 1e-9;
  const double tck = static_cast<double>(::sysconf(_SC_CLK_TCK));
  const std::uint64_t imu_in_window = at_end.imu_samples - at_start.imu_samples;

  std::printf("rilod exit code %d after %.1f s; %llu odometry received of %llu published\n", exit_code, wall_s,
              static_cast<unsigned long long>(received), static_cast<unsigned long long>(last.published_odometry));
  std::printf("\nIMU sample -> DDS receive (other process, loopback), %zu messages over %.1f s of tracking:\n",
              latency_ms.size(), window_s);
  std::printf("  p50 %.3f ms  p90 %.3f ms  p99 %.3f ms  p99.9 %.3f ms  max %.3f ms\n", percentile(latency_ms, 0.5),
              percentile(latency_ms, 0.9), percentile(latency_ms, 0.99), percentile(latency_ms, 0.999),
              percentile(latency_ms, 1.0));
  std::printf("  in-service (sample in -> DDS write returned), worst per 1 s status period: median %.3f ms, max %.3f ms\n",
              percentile(service_latency_ms, 0.5), service_latency_max_ms);
  std::printf(
      "\nEstimator budget (rilod's status, whole run): smoother update mean %.3f ms, p99 %.3f ms (within ~10 %% "
      "above), max %.3f ms; late updates %llu; queues' high water %u samples to the estimator, %u to the publisher "
      "(of realtime.queue_capacity, 16384 by default), overflows %llu\n",
      last.mean_update_ms, last.p99_update_ms, last.max_update_ms, static_cast<unsigned long long>(last.late_updates),
      last.estimator_queue_high_water, last.publisher_queue_high_water,
      static_cast<unsigned long long>(last.queue_overflows));
  const double total_cpu_s = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                             static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) * 1e-6;
  std::printf("\nCPU of rilod, whole run (wait4): %.2f s user+sys over %.1f s = %.1f %% of one core "
              "(start-up and initialization included)\n",
              total_cpu_s, wall_s, 100.0 * total_cpu_s / wall_s);
  auto byName = [](const std::map<int, ThreadCpu>& from, const std::map<int, ThreadCpu>& to, long& total) {
    std::map<std::string, long> out;
    total = 0;
    for (const auto& [tid, t] : to) {
      const auto it = from.find(tid);
      const long ticks = t.ticks - (it != from.end() ? it->second.ticks : 0);
      total += ticks;
      out[t.name] += ticks;
    }
    return out;
  };
  long window_ticks = 0, init_ticks = 0;
  const std::map<std::string, long> by_name = byName(cpu_start, cpu_end, window_ticks);
  const std::map<std::string, long> init_by_name = byName(init_cpu_start, init_cpu_end, init_ticks);
  const double init_s = static_cast<double>(init_end_ns - init_start_ns) * 1e-9;
  std::printf("CPU of rilod while tracking (%.1f s, %llu IMU samples = %.0f Hz, %llu ranges): %.1f %% of one core\n",
              window_s, static_cast<unsigned long long>(imu_in_window),
              window_s > 0 ? static_cast<double>(imu_in_window) / window_s : 0.0,
              static_cast<unsigned long long>(at_end.range_samples - at_start.range_samples),
              window_s > 0 ? 100.0 * static_cast<double>(window_ticks) / tck / window_s : 0.0);
  for (const auto& [name, ticks] : by_name) {
    const double s = static_cast<double>(ticks) / tck;
    const auto init = init_by_name.find(name);
    const double init_pct = init != init_by_name.end() && init_s > 0
                                ? 100.0 * static_cast<double>(init->second) / tck / init_s
                                : 0.0;
    std::printf("  %-16s %6.1f %% of one core (initializing: %5.1f %%)", name.c_str(),
                window_s > 0 ? 100.0 * s / window_s : 0.0, init_pct);
    if (imu_in_window > 0 && (name == "rilo-replay" || name == "rilo-publisher")) {
      std::printf("  (%.1f us per IMU sample)", 1e6 * s / static_cast<double>(imu_in_window));
    }
    std::printf("\n");
  }
  std::printf("(initializing: %.1f s before tracking, no odometry published; CPU ticks of %.0f ms: per-thread "
              "figures below ~1 %% are coarse.)\n",
              init_s, 1000.0 / tck);
  return exit_code == 0 ? 0 : 1;
}
