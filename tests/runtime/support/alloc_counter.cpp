// Replacement allocation functions for the runtime test binary. They count
// only on a thread with an AllocationCounter alive (thread-local flags with
// constant initialization: no allocation, no guard variables), so the rest of
// the tests and gtest itself run unaffected.
#include "runtime/support/alloc_counter.h"

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#include "runtime/sanitizers.h"

namespace {

thread_local bool t_counting = false;
thread_local std::uint64_t t_allocations = 0;
thread_local std::uint64_t t_deallocations = 0;

inline void noteAllocation() noexcept {
  if (t_counting) ++t_allocations;
}
inline void noteDeallocation(const void* p) noexcept {
  if (t_counting && p != nullptr) ++t_deallocations;
}

}  // namespace

#ifndef RILO_TEST_NO_MALLOC_INTERPOSE
#if defined(RILO_HAS_TSAN) || defined(RILO_HAS_ASAN)
#define RILO_TEST_NO_MALLOC_INTERPOSE 1
#endif
#endif

#ifndef RILO_TEST_NO_MALLOC_INTERPOSE
// glibc exports its allocator under these names, so the executable can define
// malloc & co. (symbol interposition) and forward to them. Everything else in
// glibc (memalign, valloc, malloc_usable_size) stays compatible.
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);

void* malloc(std::size_t size) noexcept {
  noteAllocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) noexcept {
  noteAllocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  noteAllocation();
  return __libc_realloc(p, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  noteAllocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  noteAllocation();
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* p) noexcept {
  noteDeallocation(p);
  __libc_free(p);
}
}  // extern "C"

namespace {
void* rawAllocate(std::size_t size) noexcept { return __libc_malloc(size); }
void* rawAllocateAligned(std::size_t size, std::size_t alignment) noexcept {
  return __libc_memalign(alignment, size);
}
void rawFree(void* p) noexcept { __libc_free(p); }
}  // namespace
#else
namespace {
// Sanitizer runtimes intercept malloc; operator new goes through them.
void* rawAllocate(std::size_t size) noexcept { return std::malloc(size); }
void* rawAllocateAligned(std::size_t size, std::size_t alignment) noexcept {
  return std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
}
void rawFree(void* p) noexcept { std::free(p); }
}  // namespace
#endif

namespace {

void* allocate(std::size_t size) noexcept {
  noteAllocation();
  return rawAllocate(size == 0 ? 1 : size);
}
void* allocateAligned(std::size_t size, std::align_val_t alignment) noexcept {
  noteAllocation();
  return rawAllocateAligned(size == 0 ? 1 : size, static_cast<std::size_t>(alignment));
}
void deallocate(void* p) noexcept {
  noteDeallocation(p);
  rawFree(p);
}
void* orThrow(void* p) {
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace

// Every replaceable form ([new.delete]): plain, array, nothrow, aligned, sized.
void* operator new(std::size_t size) { return orThrow(allocate(size)); }
void* operator new[](std::size_t size) { return orThrow(allocate(size)); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return allocate(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept { return allocate(size); }
void* operator new(std::size_t size, std::align_val_t al) { return orThrow(allocateAligned(size, al)); }
void* operator new[](std::size_t size, std::align_val_t al) { return orThrow(allocateAligned(size, al)); }
void* operator new(std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return allocateAligned(size, al);
}
void* operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return allocateAligned(size, al);
}

void operator delete(void* p) noexcept { deallocate(p); }
void operator delete[](void* p) noexcept { deallocate(p); }
void operator delete(void* p, std::size_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::size_t) noexcept { deallocate(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete(void* p, std::align_val_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::align_val_t) noexcept { deallocate(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { deallocate(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { deallocate(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { deallocate(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { deallocate(p); }

namespace rilo::testing {

AllocationCounter::AllocationCounter() noexcept {
  t_allocations = 0;
  t_deallocations = 0;
  t_counting = true;
}
AllocationCounter::~AllocationCounter() { t_counting = false; }
std::uint64_t AllocationCounter::allocations() const noexcept { return t_allocations; }
std::uint64_t AllocationCounter::deallocations() const noexcept { return t_deallocations; }

bool countsMalloc() noexcept {
#ifdef RILO_TEST_NO_MALLOC_INTERPOSE
  return false;
#else
  return true;
#endif
}

}  // namespace rilo::testing
