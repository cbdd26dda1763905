#pragma once
// Counts heap allocations and lock acquisitions per enrolled thread, for
// proving that the threads rilod starts (source, publisher) neither allocate
// nor lock per IMU sample. Unlike
// tests/runtime's AllocationCounter (counts on the thread that owns it), the
// counts live in a ThreadAllocations object any thread can read while the
// counted thread runs: the test enrolls the service's threads from their
// ServiceOptions::on_thread_enter hook and arms counting after warm-up.
//
// Counted: every global operator new and, outside sanitizer builds, every
// malloc/calloc/realloc/aligned_alloc/posix_memalign (interposed in the test
// binary; Eigen and Cyclone allocate with malloc); and, outside sanitizer
// builds, every pthread_mutex_lock/trylock and pthread_rwlock_rdlock/wrlock
// (std::mutex, std::shared_mutex and Cyclone's ddsrt locks all end there).
// What happens inside Cyclone's dds_write_ts is counted apart (the test binary
// links with -Wl,--wrap=dds_write_ts; the wrapper marks the call): Cyclone
// 0.10's write does one malloc and one realloc per sample (the serialized
// sample) and takes its writer's locks, which is not rilo's code and is
// measured, not hidden.
#include <atomic>
#include <cstdint>

namespace rilo::testing {

struct ThreadActivity {
  std::atomic<std::uint64_t> allocations{0};          ///< in rilo's code (and the libstdc++/Eigen/glibc it calls)
  std::atomic<std::uint64_t> locks{0};                ///< mutex/rwlock acquisitions in rilo's code
  std::atomic<std::uint64_t> cyclone_allocations{0};  ///< inside dds_write_ts
  std::atomic<std::uint64_t> cyclone_locks{0};        ///< inside dds_write_ts
  std::atomic<std::uint64_t> dds_writes{0};           ///< dds_write_ts calls
};

/// The calling thread counts into `counts` from now on (while armed).
void enrollThisThread(ThreadActivity& counts) noexcept;
/// Starts / stops counting on every enrolled thread.
void armThreadCounting(bool armed) noexcept;
/// True when malloc and friends and the pthread locks are counted (not in
/// sanitizer builds, whose runtimes intercept them); operator new always is.
bool countsMallocAndLocks() noexcept;

}  // namespace rilo::testing
