#pragma once
// The fuzz targets (issue 37): each takes one input of any bytes and returns
// 0. A parser may refuse an input only with its own documented error
// (RecordingError, TumError, ConfigError); anything else escaping, a crash,
// or a sanitizer report is a finding. Built two ways:
//  - scripts/fuzz.sh: with clang's libFuzzer, ASan and UBSan, one executable
//    per target (RILO_LIBFUZZER defines LLVMFuzzerTestOneInput);
//  - every build: the committed corpora (tests/fuzz/corpus/<target>/) are
//    replayed through the same functions as ordinary tests (ctest -L fuzz).
#include <cstddef>
#include <cstdint>

namespace rilo::fuzz {

int recordingCsv(const std::uint8_t* data, std::size_t size);
int metaYaml(const std::uint8_t* data, std::size_t size);
int rilodConfig(const std::uint8_t* data, std::size_t size);
int tumTrajectory(const std::uint8_t* data, std::size_t size);
int bmi263Fifo(const std::uint8_t* data, std::size_t size);
int dw3000Frame(const std::uint8_t* data, std::size_t size);

}  // namespace rilo::fuzz

#ifdef RILO_LIBFUZZER
#define RILO_FUZZ_ENTRY(function)                                                        \
  extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) { \
    return rilo::fuzz::function(data, size);                                             \
  }
#else
#define RILO_FUZZ_ENTRY(function)
#endif
