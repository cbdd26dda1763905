#pragma once
// One TDoA row for tests that feed estimators by hand.
#include <cstdint>

#include "sensors/samples.h"

namespace rilo::testing {

/// Range difference |p - anchor_b| - |p - anchor_a| (m) at t_ns.
inline TdoaSample tdoaRow(std::int64_t t_ns, std::uint32_t anchor_a, std::uint32_t anchor_b, double diff_m) {
  TdoaSample row;
  row.t_ns = t_ns;
  row.anchor_a = anchor_a;
  row.anchor_b = anchor_b;
  row.diff_m = diff_m;
  return row;
}

}  // namespace rilo::testing
