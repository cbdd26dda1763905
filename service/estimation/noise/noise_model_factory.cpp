#include "estimation/noise/noise_model_factory.h"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <tuple>

#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/cauchy_loss.h"
#include "estimation/noise/gaussian_loss.h"
#include "estimation/noise/huber_loss.h"
#include "estimation/noise/nlos_component_loss.h"

namespace rilo {
namespace {

/// Asymmetric losses by (component, gamma/sigma, weight). Building one
/// tabulates its convolution (tens of microseconds), and the initializer's
/// every batch graph asks for the same one: about 6% of a replay. Losses are
/// immutable, so sharing them is safe; the cache holds the few distinct
/// parameter sets a process uses.
RobustLossPtr sharedAsymmetricLoss(double gamma_over_sigma, double nlos_weight, AsymmetricLoss::Component component) {
  static std::mutex mutex;
  static std::map<std::tuple<int, double, double>, RobustLossPtr> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  RobustLossPtr& loss = cache[{static_cast<int>(component), gamma_over_sigma, nlos_weight}];
  if (!loss) loss = std::make_shared<AsymmetricLoss>(gamma_over_sigma, nlos_weight, component);
  return loss;
}

/// gamma in LOS sigmas after validating sigma_m and nlos_scale_m.
double asymmetricGammaOverSigma(const RangeNoiseParams& params, const char* who) {
  if (!std::isfinite(params.sigma_m) || params.sigma_m <= 0.0) {
    throw std::invalid_argument(std::string(who) + ": sigma_m must be finite and > 0 (got " +
                                std::to_string(params.sigma_m) + ")");
  }
  const double gamma_m = params.nlosScaleM();
  if (!std::isfinite(gamma_m) || gamma_m <= 0.0) {
    throw std::invalid_argument(std::string(who) + ": nlos_scale_m must be finite and > 0 (got " +
                                std::to_string(gamma_m) + ")");
  }
  return gamma_m / params.sigma_m;
}

}  // namespace

std::shared_ptr<const NlosComponentLoss> makeNlosComponentLoss(const RangeNoiseParams& params) {
  const double gamma = asymmetricGammaOverSigma(params, "makeNlosComponentLoss");
  static std::mutex mutex;
  static std::map<double, std::shared_ptr<const NlosComponentLoss>> cache;
  const std::lock_guard<std::mutex> lock(mutex);
  std::shared_ptr<const NlosComponentLoss>& loss = cache[gamma];
  if (!loss) loss = std::make_shared<NlosComponentLoss>(gamma);
  return loss;
}

const std::vector<std::string>& rangeLossNames() {
  static const std::vector<std::string> kNames = {"gaussian", "huber", "cauchy", "asymmetric",
                                                  "asymmetric-half-cauchy"};
  return kNames;
}

RobustLossPtr makeRangeLoss(const std::string& name, const RangeNoiseParams& params) {
  if (name == "gaussian") return std::make_shared<GaussianLoss>();
  if (name == "huber") return std::make_shared<HuberLoss>(params.huber_k);
  if (name == "cauchy") return std::make_shared<CauchyLoss>(params.cauchy_c);
  if (name == "asymmetric" || name == "asymmetric-half-cauchy") {
    const double gamma = asymmetricGammaOverSigma(params, "makeRangeLoss");
    const auto component = name == "asymmetric" ? AsymmetricLoss::Component::kConvolved
                                                : AsymmetricLoss::Component::kHalfCauchy;
    return sharedAsymmetricLoss(gamma, params.nlos_weight, component);
  }
  std::string valid;
  for (const std::string& n : rangeLossNames()) valid += (valid.empty() ? "" : ", ") + n;
  throw std::invalid_argument("makeRangeLoss: unknown range noise model '" + name + "' (valid: " + valid + ")");
}

}  // namespace rilo
