#include "estimation/noise/tdoa_gap_excess.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

void TdoaGapExcessParams::validate() const {
  auto need = [](bool ok, const char* field, double v) {
    if (!ok) throw std::invalid_argument(std::string("TdoaGapExcessParams.") + field + " out of range: " + std::to_string(v));
  };
  need(std::isfinite(bin_db) && bin_db > 0.0, "bin_db", bin_db);
  need(std::isfinite(los_gap_db) && los_gap_db >= 0.0, "los_gap_db", los_gap_db);
  need(std::isfinite(clip_m) && clip_m > 0.0, "clip_m", clip_m);
  need(std::isfinite(window_rows) && window_rows >= 1.0, "window_rows", window_rows);
  need(min_rows >= 1, "min_rows", min_rows);
}

TdoaGapExcess::TdoaGapExcess(const TdoaGapExcessParams& params) : params_(params) { params_.validate(); }

int TdoaGapExcess::binOf(double gap_db) const noexcept {
  if (!(gap_db >= params_.los_gap_db)) return -1;  // NaN too
  const double b = std::floor(gap_db / params_.bin_db);
  return static_cast<int>(std::min(b, static_cast<double>(kBins - 1)));
}

void TdoaGapExcess::add(double gap_a_db, double gap_b_db, double residual_m) noexcept {
  if (std::isnan(gap_a_db) || std::isnan(gap_b_db) || !std::isfinite(residual_m)) return;
  const int a = binOf(gap_a_db), b = binOf(gap_b_db);
  if (a == b) return;  // both LOS, or one bin on both sides: the row says nothing about the table
  const double f_a = a < 0 ? 0.0 : excess_m_[a];
  const double f_b = b < 0 ? 0.0 : excess_m_[b];
  const double e = std::clamp(residual_m - (f_b - f_a), -params_.clip_m, params_.clip_m);
  auto step = [&](int bin, double sign) {
    const double n = static_cast<double>(++rows_[bin]);
    excess_m_[bin] += sign * std::max(1.0 / n, 1.0 / params_.window_rows) * e;
  };
  if (b >= 0) step(b, 1.0);
  if (a >= 0) step(a, -1.0);
  ++learnt_;
}

double TdoaGapExcess::excess(double gap_db) const noexcept {
  const int bin = binOf(gap_db);
  return bin >= 0 && rows_[bin] >= params_.min_rows ? excess_m_[bin] : 0.0;
}

double TdoaGapExcess::correction(double gap_a_db, double gap_b_db) const noexcept {
  if (std::isnan(gap_a_db) || std::isnan(gap_b_db)) return 0.0;
  return excess(gap_b_db) - excess(gap_a_db);
}

std::int64_t TdoaGapExcess::rows(double gap_db) const noexcept {
  const int bin = binOf(gap_db);
  return bin < 0 ? 0 : rows_[bin];
}

void TdoaGapExcess::reset() noexcept {
  excess_m_.fill(0.0);
  rows_.fill(0);
  learnt_ = 0;
}

}  // namespace rilo
