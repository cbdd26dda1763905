#include "estimation/graph/values.h"

#include <algorithm>

namespace rilo {

std::string keyString(Key k) {
  const char s = keySymbol(k);
  std::string out = std::to_string(keyIndex(k));
  out.insert(out.begin(), (s >= 32 && s < 127) ? s : '?');
  return out;
}

int variableDim(const Variable& v) {
  return std::visit([](const auto& x) -> int {
    using T = std::decay_t<decltype(x)>;
    if constexpr (std::is_same_v<T, Vec3>) return 3; else return T::kDim;
  }, v);
}

Variable retractVariable(const Variable& v, const double* d) {
  return std::visit([d](const auto& x) -> Variable {
    using T = std::decay_t<decltype(x)>;
    if constexpr (std::is_same_v<T, Vec3>) {
      return Vec3(x + Eigen::Map<const Vec3>(d));
    } else {
      return x.retract(Eigen::Map<const Vec6>(d));
    }
  }, v);
}

Eigen::VectorXd localVariable(const Variable& a, const Variable& b) {
  if (a.index() != b.index()) throw std::invalid_argument("localVariable: variables of different types");
  return std::visit([&b](const auto& x) -> Eigen::VectorXd {
    using T = std::decay_t<decltype(x)>;
    const T& y = std::get<T>(b);
    if constexpr (std::is_same_v<T, Vec3>) {
      return y - x;
    } else {
      return x.local(y);
    }
  }, a);
}

void Values::insert(Key k, const Variable& v) {
  if (!map_.emplace(k, v).second) throw std::invalid_argument("Values::insert: key " + keyString(k) + " exists");
}

void Values::update(Key k, const Variable& v) {
  auto it = map_.find(k);
  if (it == map_.end()) throw std::out_of_range("Values::update: key " + keyString(k) + " missing");
  it->second = v;
}

const Variable& Values::at(Key k) const {
  auto it = map_.find(k);
  if (it == map_.end()) throw std::out_of_range("Values: key " + keyString(k) + " missing");
  return it->second;
}

std::vector<Key> Values::keys() const {
  std::vector<Key> ks;
  ks.reserve(map_.size());
  for (const auto& kv : map_) ks.push_back(kv.first);
  std::sort(ks.begin(), ks.end());
  return ks;
}

void Values::retractInPlace(Key k, const double* delta) {
  auto it = map_.find(k);
  if (it == map_.end()) throw std::out_of_range("Values::retractInPlace: key " + keyString(k) + " missing");
  it->second = retractVariable(it->second, delta);
}

}  // namespace rilo
