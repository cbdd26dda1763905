#pragma once
// Splits a batch factor graph into the increments a smoother would receive
// in real time: increment k holds the factors whose newest state index is k
// (anchors do not count) and the values of the keys they introduce.
#include <algorithm>
#include <unordered_set>
#include <vector>

#include "estimation/graph/factor.h"
#include "estimation/smoother/smoother.h"

namespace rilo::testing {

struct Increment {
  FactorGraph factors;
  Values values;
  KeyTimestamps timestamps;
};

inline bool isStateKey(Key k) {
  const char s = keySymbol(k);
  return s == 'x' || s == 'v' || s == 'b';
}

/// `state_t_ns[i]` timestamps the keys X/V/B(i) (empty: no timestamps).
inline std::vector<Increment> splitIntoIncrements(const FactorGraph& graph, const Values& initial,
                                                  const std::vector<std::int64_t>& state_t_ns = {}) {
  std::vector<Increment> out;
  auto newest = [](const FactorPtr& f) {
    std::uint64_t n = 0;
    for (Key k : f->keys()) {
      if (isStateKey(k)) n = std::max(n, keyIndex(k));
    }
    return n;
  };
  for (const FactorPtr& f : graph) {
    const std::size_t k = newest(f);
    if (out.size() <= k) out.resize(k + 1);
    out[k].factors.add(f);
  }
  std::unordered_set<Key> seen;
  for (Increment& inc : out) {
    for (const FactorPtr& f : inc.factors) {
      for (Key k : f->keys()) {
        if (!seen.insert(k).second) continue;
        inc.values.insert(k, initial.at(k));
        if (isStateKey(k) && keyIndex(k) < state_t_ns.size()) inc.timestamps[k] = state_t_ns[keyIndex(k)];
      }
    }
  }
  return out;
}

}  // namespace rilo::testing
