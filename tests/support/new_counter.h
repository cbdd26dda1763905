#pragma once
// Counts global operator new calls on the calling thread while alive. The
// counting operator new and the flags live in tests/core/ekf_alloc_test.cpp
// (one replacement per binary): only the core test binary links them.
#include <cstdint>

namespace rilo::testing {

extern constinit thread_local bool t_counting_news;
extern constinit thread_local std::uint64_t t_news;

class NewCounter {
 public:
  NewCounter() noexcept {
    t_news = 0;
    t_counting_news = true;
  }
  ~NewCounter() { t_counting_news = false; }
  NewCounter(const NewCounter&) = delete;
  NewCounter& operator=(const NewCounter&) = delete;
  std::uint64_t count() const noexcept { return t_news; }
};

}  // namespace rilo::testing
