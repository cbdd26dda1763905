#pragma once
// `rilo range-errors REC...`: how each recording's two-way ranges err against
// its ground truth (evaluation/range_errors.h): quantiles, the share too
// short for any NLOS path and too long, and the error's slope on the radial
// speed, for all ranges, per LOS label where the recording has one, and per
// anchor. --csv FILE writes every range's error for a closer look.
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace rilo::tool {

struct RangeErrorsCommandOptions {
  std::vector<std::string> recordings;  ///< folders with groundtruth.csv
  std::string csv;                      ///< per-range CSV (empty: none)
  double threshold_m = 0.3;             ///< |error| beyond this counts as short / long
  double truth_shift_s = 0.0;           ///< RangeErrorOptions::truth_shift_s
};

/// Returns the process exit code (0: printed; 1: bad input or I/O failure, the message on stderr).
int runRangeErrorsCommand(const RangeErrorsCommandOptions& options);

/// Registers the `range-errors` subcommand. Link: rilo_evaluation, CLI11.
void addRangeErrorsCommand(CLI::App& app);

}  // namespace rilo::tool
