// propagate() and the updates of the error-state EKF never allocate.
//
// This file replaces the global operator new/delete of the core test binary
// with versions that forward to malloc/free and count, on the calling thread
// only, while a NewCounter (support/new_counter.h, usable from other test
// files of the binary) is alive (thread-local flags, constant-initialized:
// the rest of the binary is unaffected). The array, nothrow and sized forms
// of the standard library forward to these two; the aligned forms (not used
// by rilo) keep the library's own aligned_alloc/free pair. Eigen's dynamic
// matrices allocate with malloc and are not counted here; the filter uses
// fixed-size types only (see error_state_ekf.h).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <new>

#include "estimation/ekf/error_state_ekf.h"
#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/huber_loss.h"
#include "support/new_counter.h"

namespace rilo::testing {

constinit thread_local bool t_counting_news = false;
constinit thread_local std::uint64_t t_news = 0;

}  // namespace rilo::testing

void* operator new(std::size_t size) {
  if (rilo::testing::t_counting_news) ++rilo::testing::t_news;
  void* p = std::malloc(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  return p;
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace rilo {
namespace {

using testing::NewCounter;

TEST(EkfAllocation, CounterSeesAllocations) {
  std::uint64_t n = 0;
  {
    NewCounter counter;
    static std::uint64_t* volatile sink = nullptr;  // volatile: the pair may not be elided
    sink = new std::uint64_t(3);
    n = counter.count();
    delete sink;
  }
  EXPECT_EQ(n, 1u);
}

TEST(EkfAllocation, PropagateAndUpdatesDoNotAllocate) {
  ErrorStateEkf ekf;
  Vec15 s;
  s << Vec3::Constant(0.05), Vec3::Constant(0.3), Vec3::Constant(0.2), Vec3::Constant(0.05), Vec3::Constant(0.005);
  ekf.initialize(0, EkfState(Pose3(Mat3::Identity(), Vec3(1, 2, 1.2)), Vec3::Zero(), ImuBias()),
                 Mat15(s.cwiseAbs2().asDiagonal()));
  const HuberLoss huber;
  const AsymmetricLoss nlos(5.0, 0.2);  // builds its table here, outside the counted region
  const Vec3 A(5, 5, 2.5), B(-5, 4, 0.3), C(0, -5, 2.8), lever(0.1, 0, 0.2);
  ImuSample imu;
  imu.accel_m_s2 = Vec3(0.1, -0.05, 9.81);
  imu.gyro_rad_s = Vec3(0.01, 0.02, 0.3);

  std::uint64_t news = 0;
  int accepted = 0, gated = 0;
  {
    NewCounter counter;
    for (int k = 0; k < 200; ++k) {
      imu.t_ns = 5'000'000LL * k;
      ekf.propagate(imu);
      if (k % 5 == 0) {
        const double r = predictRange(ekf.state(), A, lever).h(0);
        accepted += ekf.updateRange(A, lever, r + 0.05, 0.1, &huber).accepted();
        accepted += ekf.updateRange(A, lever, r + 0.3, 0.1, &nlos).accepted();
        gated += ekf.updateRange(A, lever, r + 5.0, 0.1).status == UpdateStatus::kGated;
        const double d = predictTdoa(ekf.state(), A, B, lever).h(0);
        accepted += ekf.updateTdoa(A, B, lever, d - 0.02, 0.1, &huber).accepted();
        const double u = predictUltrasonic(ekf.state(), C, lever).h(0);
        accepted += ekf.updateUltrasonic(C, lever, u, 0.02, UltrasonicElevation{-1.4, 0.1}).accepted();
        accepted += ekf.updateUltrasonic(C, lever, u, 0.02, std::nullopt, &nlos).accepted();
      }
    }
    news = counter.count();
  }
  EXPECT_EQ(news, 0u);
  EXPECT_GT(accepted, 100);
  EXPECT_EQ(gated, 40);
}

}  // namespace
}  // namespace rilo
