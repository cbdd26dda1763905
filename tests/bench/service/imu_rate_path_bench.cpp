// rilod's IMU-rate path per sample, assembled from the real parts in the order
// service.cpp runs them:
//  - source side (Service::LaneSink::push): clock read, entrance screen
//    (SampleScreen), push into the estimator's queue and into the
//    publisher's IMU queue, counters, the publisher's wake-up signal (here
//    without a sleeping publisher: no system call);
//  - publisher side (the body of Service::publisherLoop): pop, output
//    predictor, odometry fill and Cyclone dds_write_ts on loopback, counter,
//    clock read, latency maximum.
// The service's own threads are measured by the rilod-measure tool (CPU per
// thread at 800 Hz, which adds the polling and the wake-ups); this is the
// compute cost of one sample. Arg: 0 = no subscriber, 1 = a subscriber in
// this process (Cyclone delivers locally, in the writing thread).
//
// Measured (Release, shared 2-core x86-64 under load average ~5, medians of 5
// repetitions, CPU time; wall time was 1.5-2x that from preemption):
//   BM_ImuRatePathSourceSide          45 ns
//   BM_ImuRatePathPublisherSide/0    0.79 us  (dds_write_ts is most of it)
//   BM_ImuRatePathPublisherSide/1    0.89 us
//   BM_ImuRatePathPerSample          0.73 us
// With a subscriber in another process the write also does the sendmsg on
// loopback: 30-50 us (tests/dds write cost), see rilod-measure.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "dds/participant.h"
#include "dds/publisher.h"
#include "dds/subscriber.h"
#include "hal/bus/clock.h"
#include "rilod/sample_screen.h"
#include "runtime/latest_value.h"
#include "runtime/output_predictor.h"
#include "runtime/runtime_counters.h"
#include "runtime/spsc_queue.h"
#include "runtime/wake_signal.h"
#include "sim/trajectory.h"

namespace rilo {
namespace {

constexpr double kImuRateHz = 800.0;
constexpr std::int64_t kImuPeriodNs = 1'250'000;
constexpr std::uint32_t kDomain = 231;  // loopback only; outside the tests' 100..229

/// As service.cpp's TimedImu.
struct TimedImu {
  ImuSample sample;
  std::int64_t arrival_ns = 0;
};

std::vector<ImuSample> walkSamples(int n) {
  const sim::LissajousWalk walk;
  std::vector<ImuSample> samples(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const sim::ImuReading r = sim::idealImu(walk.at(1.0 + k / kImuRateHz));
    samples[static_cast<std::size_t>(k)].gyro_rad_s = r.gyro;
    samples[static_cast<std::size_t>(k)].accel_m_s2 = r.accel;
  }
  return samples;
}

NavigationState startState() {
  const sim::KinematicState k = sim::LissajousWalk().at(1.0);
  NavigationState s;
  s.q_w_b = Quat(k.T_w_b.R);
  s.p_w_b = k.T_w_b.p;
  s.v_w_b = k.v_w;
  s.valid = true;
  return s;
}

void atomicMax(std::atomic<std::int64_t>& target, std::int64_t value) noexcept {
  std::int64_t current = target.load(std::memory_order_relaxed);
  while (value > current && !target.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
}

/// Everything one rilod instance owns on the IMU-rate path.
struct Path {
  explicit Path(bool subscriber)
      : participant(options()), publisher(participant), samples(4096), imu(4096), predictor() {
    if (subscriber) {
      reader_participant = std::make_unique<dds::Participant>(options());
      dds::SubscriberOptions so;
      so.pose = false;
      so.status = false;
      reader = std::make_unique<dds::Subscriber>(*reader_participant, so);
      publisher.waitForSubscribers(dds::TopicKind::kOdometry, 1, std::chrono::seconds(10));
    }
    predictor.onSmoothed(startState());
  }
  static dds::ParticipantOptions options() {
    dds::ParticipantOptions po;
    po.domain_id = kDomain;
    po.config_xml = dds::loopbackConfigXml();
    return po;
  }

  // LaneSink::push
  void push(const ImuSample& s) noexcept {
    const std::int64_t now = hal::monotonicNowNs();
    const Sample sample{s};
    if (screen.check(sample) != SampleVerdict::kAccept) return;
    if (!samples.tryPush(sample)) counters.queue_overflows.add();
    counters.imu_samples.add();
    if (!imu.tryPush(TimedImu{s, now})) counters.queue_overflows.add();
    wake.notify();  // no waiter here: the increment and the load, not the system call
  }
  // One sample of Service::publisherLoop.
  void publish() noexcept {
    TimedImu item;
    if (!imu.tryPop(item)) return;
    const NavigationState& out = predictor.onImu(item.sample);
    if (out.valid && publisher.publishOdometry(out).ok()) {
      (void)publisher.publishTransform(out);  // TF with the odometry (rt/tf), as the service does
      counters.published_odometry.add();
      atomicMax(latency_max_ns, hal::monotonicNowNs() - item.arrival_ns);
    }
  }
  // What the estimator thread does with the sample queue (not the IMU-rate path).
  void drainEstimatorQueue() noexcept {
    Sample s;
    while (samples.tryPop(s)) {
    }
  }

  dds::Participant participant;
  dds::Publisher publisher;
  std::unique_ptr<dds::Participant> reader_participant;
  std::unique_ptr<dds::Subscriber> reader;
  SampleScreen screen;
  SpscQueue<Sample> samples;
  SpscQueue<TimedImu> imu;
  OutputPredictor predictor;
  RuntimeCounters counters;
  WakeSignal wake;
  std::atomic<std::int64_t> latency_max_ns{0};
};

// The consumers' pops are included (a few ns each, see BM_SpscPushPop):
// pausing the timer per sample would cost more than what is measured.
void BM_ImuRatePathSourceSide(benchmark::State& state) {
  Path path(false);
  const std::vector<ImuSample> motion = walkSamples(800);
  std::int64_t t_ns = 0;
  std::size_t k = 0;
  TimedImu drop;
  for (auto _ : state) {
    ImuSample s = motion[k++ % motion.size()];
    s.t_ns = (t_ns += kImuPeriodNs);
    path.push(s);
    path.drainEstimatorQueue();
    path.imu.tryPop(drop);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_ImuRatePathSourceSide);

// The publisher's share: its IMU queue is refilled by the source side, untimed,
// 2048 samples at a time.
void BM_ImuRatePathPublisherSide(benchmark::State& state) {
  Path path(state.range(0) != 0);
  const std::vector<ImuSample> motion = walkSamples(800);
  std::int64_t t_ns = 0;
  std::size_t k = 0, queued = 0;
  std::vector<dds::OdometryMessage> taken;
  for (auto _ : state) {
    if (queued == 0) {
      state.PauseTiming();
      for (; queued < 2048; ++queued) {
        ImuSample s = motion[k++ % motion.size()];
        s.t_ns = (t_ns += kImuPeriodNs);
        path.push(s);
      }
      path.drainEstimatorQueue();
      if (path.reader) {
        taken.clear();
        path.reader->takeOdometry(taken);
      }
      state.ResumeTiming();
    }
    path.publish();
    --queued;
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_ImuRatePathPublisherSide)->Arg(0)->Arg(1);

// Both sides back to back on one thread: the compute the two real-time
// threads spend per IMU sample (without the cache transfer between them).
void BM_ImuRatePathPerSample(benchmark::State& state) {
  Path path(false);
  const std::vector<ImuSample> motion = walkSamples(800);
  std::int64_t t_ns = 0;
  std::size_t k = 0;
  for (auto _ : state) {
    ImuSample s = motion[k++ % motion.size()];
    s.t_ns = (t_ns += kImuPeriodNs);
    path.push(s);
    path.publish();
    path.drainEstimatorQueue();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_ImuRatePathPerSample);

}  // namespace
}  // namespace rilo
