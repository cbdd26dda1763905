#include "runtime/init_worker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "runtime/realtime.h"

namespace rilo {

InitWorker::InitWorker(const std::string& thread_name) {
  thread_ = std::thread([this] { run(); });
  ThreadRealtimeSettings settings;
  settings.name = thread_name;
  (void)applyThreadRealtime(thread_, settings);  // a name only: nothing that could be refused matters here
}

InitWorker::~InitWorker() {
  wait();
  state_.store(kStop, std::memory_order_release);
  state_.notify_one();
  thread_.join();
}

void InitWorker::start(std::function<void()> attempt) {
  if (!idle()) throw std::logic_error("InitWorker::start: an attempt is still running");
  attempt_ = std::move(attempt);
  state_.store(kBusy, std::memory_order_release);
  state_.notify_one();
}

void InitWorker::wait() {
  for (int s = state_.load(std::memory_order_acquire); s == kBusy; s = state_.load(std::memory_order_acquire)) {
    state_.wait(kBusy, std::memory_order_acquire);
  }
}

bool InitWorker::waitFor(double seconds) {
  if (!std::isfinite(seconds)) {
    wait();
    return true;
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(std::max(0.0, seconds));
  while (!idle() && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return idle();
}

void InitWorker::run() {
  for (;;) {
    state_.wait(kIdle, std::memory_order_acquire);
    const int s = state_.load(std::memory_order_acquire);
    if (s == kStop) return;
    if (s != kBusy) continue;
    try {
      attempt_();
    } catch (...) {
      // Initializer::attempt reports its own failures; nothing may end this thread.
    }
    attempt_ = nullptr;
    runs_.fetch_add(1, std::memory_order_relaxed);
    state_.store(kIdle, std::memory_order_release);
    state_.notify_all();
  }
}

}  // namespace rilo
