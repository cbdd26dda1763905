#pragma once
// Where the Localizer's initialization attempts run when not inside its
// process() (Localizer::setInitRunner). An attempt on a 45 s window takes
// hundreds of milliseconds (more in heavy NLOS, 5-10x more on a wearable's
// core): run on the estimator thread it outlasts the sensor queues. A runner
// executes one attempt at a time, away from the caller; the caller keeps
// buffering samples meanwhile and takes the outcome once idle() says so.
// rilod's runner is a worker thread (runtime/init_worker.h); tests drive a
// runner by hand to place the outcome at a chosen sample.
#include <functional>

namespace rilo {

class InitAttemptRunner {
 public:
  virtual ~InitAttemptRunner() = default;
  /// Runs `attempt` once, elsewhere. Called only while idle().
  virtual void start(std::function<void()> attempt) = 0;
  /// No attempt started, or the started one has returned; what it wrote is
  /// then visible to the caller (acquire). Never blocks.
  virtual bool idle() const = 0;
  /// Blocks until idle() (end of data, destruction).
  virtual void wait() = 0;
  /// Blocks until idle() or for at most `seconds` (+inf: wait()); returns idle().
  virtual bool waitFor(double seconds) = 0;
};

}  // namespace rilo
