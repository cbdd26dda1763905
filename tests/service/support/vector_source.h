#pragma once
// A SampleSource that pushes a fixed, time-ordered list of samples as fast as
// the sink takes them (service and fault-injection tests).
#include <atomic>
#include <string>
#include <utility>
#include <vector>

#include "hal/source.h"

namespace rilo::testing {

class VectorSource final : public SampleSource {
 public:
  explicit VectorSource(std::vector<Sample> samples) : samples_(std::move(samples)) {}
  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override {
    for (const Sample& s : samples_) {
      if (stop.load()) return SourceEnd::kStopped;
      sink.push(s);
    }
    return SourceEnd::kEndOfData;
  }
  std::string describe() const override { return "vector"; }

 private:
  std::vector<Sample> samples_;
};

}  // namespace rilo::testing
