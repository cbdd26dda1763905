// Replacement allocation and lock functions of the service test binary and
// the dds_write_ts wrapper (see thread_activity.h). They only count on an
// enrolled thread while counting is armed (thread-local pointer with constant
// initialization: no allocation, no guard), so every other test runs as usual.
#include "service/support/thread_activity.h"

#include <dds/dds.h>

#include <pthread.h>

#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#include "runtime/sanitizers.h"

namespace {

thread_local rilo::testing::ThreadActivity* t_counts = nullptr;
thread_local bool t_in_dds = false;
std::atomic<bool> g_armed{false};

inline bool counting() noexcept { return t_counts != nullptr && g_armed.load(std::memory_order_relaxed); }

inline void noteAllocation() noexcept {
  if (counting()) (t_in_dds ? t_counts->cyclone_allocations : t_counts->allocations).fetch_add(1, std::memory_order_relaxed);
}

[[maybe_unused]] inline void noteLock() noexcept {
  if (counting()) (t_in_dds ? t_counts->cyclone_locks : t_counts->locks).fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

// Cyclone's write, marked so that its allocations are counted apart.
extern "C" dds_return_t __real_dds_write_ts(dds_entity_t writer, const void* data, dds_time_t timestamp);
extern "C" dds_return_t __wrap_dds_write_ts(dds_entity_t writer, const void* data, dds_time_t timestamp) {
  const bool outer = t_in_dds;
  t_in_dds = true;
  const dds_return_t rc = __real_dds_write_ts(writer, data, timestamp);
  t_in_dds = outer;
  if (counting()) t_counts->dds_writes.fetch_add(1, std::memory_order_relaxed);
  return rc;
}

#if !defined(RILO_HAS_TSAN) && !defined(RILO_HAS_ASAN)
#define RILO_INTERPOSE_MALLOC 1
// glibc exports its allocator under these names, so the executable can define
// malloc & co. (symbol interposition) and forward to them.
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
void free(void* p) noexcept { __libc_free(p); }

// The locks. glibc >= 2.34 has pthread in libc and keeps the old
// __pthread_* names as compat symbols of its base version only: bind to those
// (same code as the default pthread_* ones).
#if defined(__x86_64__)
#define RILO_GLIBC_BASE_VERSION "GLIBC_2.2.5"
#elif defined(__aarch64__)
#define RILO_GLIBC_BASE_VERSION "GLIBC_2.17"
#endif
#ifdef RILO_GLIBC_BASE_VERSION
#define RILO_COUNT_LOCKS 1
int rilo_real_mutex_lock(pthread_mutex_t* m);
int rilo_real_mutex_trylock(pthread_mutex_t* m);
int rilo_real_rwlock_rdlock(pthread_rwlock_t* l);
int rilo_real_rwlock_wrlock(pthread_rwlock_t* l);
__asm__(".symver rilo_real_mutex_lock, __pthread_mutex_lock@" RILO_GLIBC_BASE_VERSION);
__asm__(".symver rilo_real_mutex_trylock, __pthread_mutex_trylock@" RILO_GLIBC_BASE_VERSION);
__asm__(".symver rilo_real_rwlock_rdlock, __pthread_rwlock_rdlock@" RILO_GLIBC_BASE_VERSION);
__asm__(".symver rilo_real_rwlock_wrlock, __pthread_rwlock_wrlock@" RILO_GLIBC_BASE_VERSION);

int pthread_mutex_lock(pthread_mutex_t* m) noexcept {
  noteLock();
  return rilo_real_mutex_lock(m);
}
int pthread_mutex_trylock(pthread_mutex_t* m) noexcept {
  noteLock();
  return rilo_real_mutex_trylock(m);
}
int pthread_rwlock_rdlock(pthread_rwlock_t* l) noexcept {
  noteLock();
  return rilo_real_rwlock_rdlock(l);
}
int pthread_rwlock_wrlock(pthread_rwlock_t* l) noexcept {
  noteLock();
  return rilo_real_rwlock_wrlock(l);
}
#endif
}  // extern "C"

namespace {
void* rawAllocate(std::size_t size) noexcept { return __libc_malloc(size); }
void* rawAllocateAligned(std::size_t size, std::size_t alignment) noexcept { return __libc_memalign(alignment, size); }
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
void* orThrow(void* p) {
  if (p == nullptr) throw std::bad_alloc();
  return p;
}

}  // namespace

// Every replaceable form ([new.delete]). Under the malloc interposition an
// operator new that calls malloc would count twice: these call the raw allocator.
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
void operator delete(void* p) noexcept { rawFree(p); }
void operator delete[](void* p) noexcept { rawFree(p); }
void operator delete(void* p, std::size_t) noexcept { rawFree(p); }
void operator delete[](void* p, std::size_t) noexcept { rawFree(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { rawFree(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { rawFree(p); }
void operator delete(void* p, std::align_val_t) noexcept { rawFree(p); }
void operator delete[](void* p, std::align_val_t) noexcept { rawFree(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { rawFree(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { rawFree(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { rawFree(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { rawFree(p); }

namespace rilo::testing {

void enrollThisThread(ThreadActivity& counts) noexcept { t_counts = &counts; }
void armThreadCounting(bool armed) noexcept { g_armed.store(armed, std::memory_order_relaxed); }
bool countsMallocAndLocks() noexcept {
#if defined(RILO_INTERPOSE_MALLOC) && defined(RILO_COUNT_LOCKS)
  return true;
#else
  return false;
#endif
}

}  // namespace rilo::testing
