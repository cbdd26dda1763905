#pragma once
// CPU facts the lock-free primitives need: the cache-line size used to keep
// indices written by different threads apart, and a spin-wait hint.
#include <cstddef>

namespace rilo {

/// Destructive-interference distance (bytes). 64 on x86-64 and the Cortex-A
/// cores rilo targets. A constant rather than
/// std::hardware_destructive_interference_size, which GCC warns may differ
/// between compiler flags (it would change struct layouts across TUs).
inline constexpr std::size_t kCacheLineBytes = 64;

/// Tells the core we are spinning (frees pipeline resources for a sibling
/// hyper-thread, lowers power); a plain no-op elsewhere.
inline void cpuRelax() noexcept {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__) || defined(__arm__)
  asm volatile("yield" ::: "memory");
#endif
}

}  // namespace rilo
