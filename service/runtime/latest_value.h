#pragma once
// Hand-over of the newest value from one writer to any number of readers
// without locks (a seqlock): the estimator publishes its smoothed
// NavigationState and the ServiceStatus; the publisher and status threads read
// them. The writer never waits; a reader retries while a write overlaps its copy.
//
// Why a seqlock rather than a triple buffer: it serves many readers (odometry
// publisher, status publisher, watchdog) with one copy of the data, and it
// needs no reader-side write, so readers do not contend with each other. Its
// cost is that a reader can fail when a write overlaps it; tryRead() bounds the
// retries so a real-time reader that preempted the writer on the same CPU keeps
// its previous value instead of spinning forever (a triple buffer would be
// wait-free on both sides, but for exactly one reader).
//
// Memory-order reasoning (Boehm, "Can seqlocks get along with programming
// language memory models?", MSPC 2012). The payload is stored as relaxed
// std::atomic<uint64_t> words, so concurrent access is never a data race (no UB,
// nothing for ThreadSanitizer to report); the sequence counter orders them:
//   writer: seq = s+1 (odd, relaxed); release fence; word stores (relaxed);
//           seq = s+2 (even, release).
//   reader: s1 = seq (acquire); word loads (relaxed); acquire fence;
//           s2 = seq (relaxed); accept iff s1 == s2 and s1 even.
// - s1's acquire pairs with the release store that made seq even, so every word
//   of that write (or a later one) is visible to the loads.
// - If any load returned a word of a later write, that write's release fence
//   synchronizes with the reader's acquire fence (fence-to-fence through that
//   word), so its odd store happens-before the load of s2 and s2 != s1: the torn
//   copy is rejected. Torn words live only in a local buffer; they are copied
//   into a T only after the check.
// ThreadSanitizer does not model standalone fences (GCC rejects them under
// -fsanitize=thread), so TSan builds use the equivalent, slightly stronger
// per-word release stores / acquire loads instead.
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "runtime/cpu_hints.h"
#include "runtime/sanitizers.h"

namespace rilo {

struct NavigationState;

/// Types LatestValue may copy as raw bytes. Trivially copyable types qualify.
/// NavigationState opts in: its members are fixed-size Eigen objects, whose
/// user-provided copy constructors (the reason they are not trivially copyable
/// by the letter of the standard) only copy their scalar arrays, plus
/// integers and a bool; it owns no pointer or resource.
template <typename T>
struct SeqlockCopyable : std::is_trivially_copyable<T> {};
template <>
struct SeqlockCopyable<NavigationState> : std::true_type {};

template <typename T>
class LatestValue {
  static_assert(SeqlockCopyable<T>::value, "LatestValue copies T as bytes: T must be trivially copyable");
  static_assert(std::is_trivially_destructible_v<T>, "T must not own resources");
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free, "words must be lock-free atomics");

 public:
  /// Retries tryRead() makes by default before giving up (a write copies a few
  /// hundred bytes, so a reader that keeps failing this long is starving the writer).
  static constexpr unsigned kDefaultReadAttempts = 64;

  /// Starts with `initial` at version 0 (nothing written yet).
  explicit LatestValue(const T& initial = T{}) noexcept { storeWords(initial); }
  LatestValue(const LatestValue&) = delete;
  LatestValue& operator=(const LatestValue&) = delete;

  /// Publishes a new value. One writer thread only (writes are not serialized).
  void write(const T& value) noexcept {
    const std::uint64_t seq = seq_.load(std::memory_order_relaxed);  // only the writer changes it
    seq_.store(seq + 1, std::memory_order_relaxed);                 // odd: write in progress
#ifndef RILO_HAS_TSAN
    std::atomic_thread_fence(std::memory_order_release);  // odd store before the word stores
#endif
    storeWords(value);
    seq_.store(seq + 2, std::memory_order_release);  // even: the words are complete
  }

  /// Copies a consistent value into `out` (untouched on failure) and its version
  /// (number of writes it reflects; 0 = the initial value). False when every one
  /// of max_attempts overlapped a write. Any number of reader threads.
  bool tryRead(T& out, std::uint64_t* version = nullptr,
               unsigned max_attempts = kDefaultReadAttempts) const noexcept {
    Words buf;
    for (unsigned attempt = 0; attempt < max_attempts; ++attempt) {
      const std::uint64_t s1 = seq_.load(std::memory_order_acquire);
      if ((s1 & 1U) == 0U) {
        loadWords(buf);
#ifndef RILO_HAS_TSAN
        std::atomic_thread_fence(std::memory_order_acquire);  // word loads before the s2 load
#endif
        if (seq_.load(std::memory_order_relaxed) == s1) {
          std::memcpy(static_cast<void*>(&out), buf.data(), sizeof(T));
          if (version != nullptr) *version = s1 / 2;
          return true;
        }
      }
      cpuRelax();
    }
    return false;
  }

  /// Like tryRead() but retries until it succeeds. Only for readers that cannot
  /// preempt the writer (other CPU, or not a higher real-time priority).
  T read(std::uint64_t* version = nullptr) const noexcept {
    T out;
    while (!tryRead(out, version)) {
    }
    return out;
  }

  /// Copies the value into `out` only if it is newer than `last_version`, and
  /// then updates last_version. For a reader that acts once per new value.
  bool readIfNewer(T& out, std::uint64_t& last_version,
                   unsigned max_attempts = kDefaultReadAttempts) const noexcept {
    if (version() <= last_version) return false;
    std::uint64_t v = 0;
    if (!tryRead(out, &v, max_attempts)) return false;
    last_version = v;  // >= the version seen above, so > the old last_version
    return true;
  }

  /// Number of completed writes (a write in progress is not counted).
  std::uint64_t version() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);
  using Words = std::array<std::uint64_t, kWords>;

  void storeWords(const T& value) noexcept {
    Words buf;
    buf[kWords - 1] = 0;  // defined bytes past the end of T
    std::memcpy(buf.data(), static_cast<const void*>(&value), sizeof(T));
    for (std::size_t i = 0; i < kWords; ++i) {
#ifdef RILO_HAS_TSAN
      words_[i].store(buf[i], std::memory_order_release);
#else
      words_[i].store(buf[i], std::memory_order_relaxed);
#endif
    }
  }

  void loadWords(Words& buf) const noexcept {
    for (std::size_t i = 0; i < kWords; ++i) {
#ifdef RILO_HAS_TSAN
      buf[i] = words_[i].load(std::memory_order_acquire);
#else
      buf[i] = words_[i].load(std::memory_order_relaxed);
#endif
    }
  }

  // Readers only read, so counter and payload may share lines with each other,
  // but (alignas) with no other object that someone else writes.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> seq_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace rilo
