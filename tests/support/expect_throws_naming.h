#pragma once
// Bad input must fail with std::invalid_argument naming the field: checks
// that fn throws one whose message contains `name`.
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>

namespace rilo::testing {

inline void expectThrowsNaming(const std::function<void()>& fn, const std::string& name) {
  try {
    fn();
    ADD_FAILURE() << "expected std::invalid_argument naming " << name;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
  }
}

}  // namespace rilo::testing
