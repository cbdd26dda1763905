#pragma once
// CLI11 converts "-3" into an unsigned option by wrapping it round
// (`rilo sim --seed -3` simulated seed 18446744073709551613, `rilo listen
// --count -1` ran for ever): every unsigned option checks its text first.
#include <CLI/CLI.hpp>

#include <string>

namespace rilo::cli {

/// A validator for unsigned options: refuses a leading minus sign (after blanks).
inline CLI::Validator notNegative() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const std::size_t first = text.find_first_not_of(" \t\n\v\f\r");  // what strtoull skips
        if (first != std::string::npos && text[first] == '-') return "must not be negative, got " + text;
        return {};
      },
      "", "not negative");
}

}  // namespace rilo::cli
