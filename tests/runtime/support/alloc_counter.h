#pragma once
// Counts the heap allocations the calling thread makes while a counter is
// alive, to prove the IMU-rate path never allocates. The replacement
// allocation functions live in alloc_counter.cpp: every form of global
// operator new/delete and, outside sanitizer builds, malloc/calloc/realloc/
// aligned_alloc/posix_memalign/free themselves (Eigen allocates with malloc).
#include <cstdint>

namespace rilo::testing {

class AllocationCounter {
 public:
  AllocationCounter() noexcept;   ///< starts counting on this thread (from zero)
  ~AllocationCounter();           ///< stops counting
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  std::uint64_t allocations() const noexcept;    ///< new/malloc-family calls so far
  std::uint64_t deallocations() const noexcept;  ///< delete/free of non-null pointers so far
};

/// True when malloc and friends are counted too (not in sanitizer builds,
/// whose runtimes own malloc); operator new/delete are always counted.
bool countsMalloc() noexcept;

}  // namespace rilo::testing
