#include "estimation/noise/weighted_loss.h"

#include <cstdio>
#include <stdexcept>
#include <utility>

namespace rilo {

WeightedLoss::WeightedLoss(RobustLossPtr inner, double w) : inner_(std::move(inner)), w_(w) {
  if (!inner_) throw std::invalid_argument("WeightedLoss: the inner loss is null");
  if (!(w > 0.0 && w <= 1.0)) throw std::invalid_argument("WeightedLoss: w must lie in (0, 1], got " + std::to_string(w));
}

std::string WeightedLoss::name() const {
  char w[32];
  std::snprintf(w, sizeof w, "%.3g", w_);
  return inner_->name() + " x " + w;
}

}  // namespace rilo
