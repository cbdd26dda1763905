// A loss counted at a fraction of its weight (estimation/noise/
// weighted_loss.h): value, derivative and IRLS weight scaled by w, the
// derivative still the value's (numerically), the asymmetric mixture's
// sides kept, bad arguments refused.
#include "estimation/noise/weighted_loss.h"

#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <stdexcept>
#include <string>

#include "estimation/noise/huber_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {
namespace {

TEST(WeightedLoss, ScalesTheInnerLossAndKeepsItsShape) {
  RangeNoiseParams n;
  n.sigma_m = 0.1;
  const RobustLossPtr mixture = makeRangeLoss("asymmetric", n);
  const WeightedLoss w(mixture, 0.25);
  EXPECT_FALSE(w.isSymmetric());
  EXPECT_NE(w.name().find(mixture->name()), std::string::npos) << w.name();
  for (double r : {-4.0, -1.0, -1e-12, 0.0, 0.3, 1.0, 2.5, 6.0, 40.0}) {
    SCOPED_TRACE(r);
    EXPECT_NEAR(w.loss(r), 0.25 * mixture->loss(r), 1e-12);
    EXPECT_NEAR(w.derivative(r), 0.25 * mixture->derivative(r), 1e-12);
    EXPECT_NEAR(w.weight(r), 0.25 * mixture->weight(r), 1e-12);
    const double h = 1e-6;
    EXPECT_NEAR(w.derivative(r), (w.loss(r + h) - w.loss(r - h)) / (2 * h), 1e-5);
  }
  // The long side stays the heavy one.
  EXPECT_LT(w.loss(4.0), w.loss(-4.0));
  const WeightedLoss one(mixture, 1.0);
  EXPECT_DOUBLE_EQ(one.loss(1.7), mixture->loss(1.7));
  EXPECT_TRUE(WeightedLoss(std::make_shared<HuberLoss>(1.345), 0.5).isSymmetric());
}

TEST(WeightedLoss, RefusesANullLossAndWeightsOutsideZeroToOne) {
  const RobustLossPtr huber = std::make_shared<HuberLoss>(1.345);
  EXPECT_THROW(WeightedLoss(nullptr, 0.5), std::invalid_argument);
  for (double bad : {0.0, -0.5, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_THROW(WeightedLoss(huber, bad), std::invalid_argument) << bad;
  }
}

}  // namespace
}  // namespace rilo
