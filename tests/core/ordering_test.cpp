#include "estimation/solver/ordering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "estimation/solver/cholmod_context.h"
#include "estimation/solver/normal_equations.h"

namespace rilo {
namespace {

// Orderings look only at keys: a factor with keys and a zero residual.
class KeysOnlyFactor : public Factor {
 public:
  explicit KeysOnlyFactor(std::vector<Key> keys) : Factor(std::move(keys)) {}
  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    r.setZero(1);
    if (H) {
      for (std::size_t k = 0; k < keys().size(); ++k) (*H)[k].setZero(1, x.dim(keys()[k]));
    }
  }
};

// A pose chain with anchors seen from every few poses and loop closures.
FactorGraph chainWithLandmarks(int n_poses, int n_landmarks, std::mt19937& rng) {
  FactorGraph g;
  std::uniform_int_distribution<int> pick_pose(0, n_poses - 1);
  g.emplace<KeysOnlyFactor>(std::vector<Key>{sym::X(0)});
  for (int i = 0; i + 1 < n_poses; ++i) {
    g.emplace<KeysOnlyFactor>(
        std::vector<Key>{sym::X(static_cast<std::uint64_t>(i)), sym::X(static_cast<std::uint64_t>(i + 1))});
  }
  for (int i = 0; i < n_poses; i += 3) {
    g.emplace<KeysOnlyFactor>(
        std::vector<Key>{sym::X(static_cast<std::uint64_t>(i)), sym::L(static_cast<std::uint64_t>(i % n_landmarks))});
  }
  for (int c = 0; c < n_poses / 10; ++c) {
    const int a = pick_pose(rng), b = pick_pose(rng);
    if (a != b) {
      g.emplace<KeysOnlyFactor>(
          std::vector<Key>{sym::X(static_cast<std::uint64_t>(a)), sym::X(static_cast<std::uint64_t>(b))});
    }
  }
  return g;
}

std::set<Key> graphKeys(const FactorGraph& g) {
  std::set<Key> keys;
  for (const auto& f : g) keys.insert(f->keys().begin(), f->keys().end());
  return keys;
}

bool isPermutationOfGraphKeys(const std::vector<Key>& order, const FactorGraph& g) {
  const std::set<Key> keys = graphKeys(g);
  const std::set<Key> ordered(order.begin(), order.end());
  return ordered.size() == order.size() && ordered == keys;
}

TEST(Ordering, ColamdReturnsEveryKeyOnce) {
  std::mt19937 rng(1);
  for (int n : {1, 2, 10, 200}) {
    const FactorGraph g = chainWithLandmarks(n, 4, rng);
    const std::vector<Key> order = colamdOrdering(g);
    EXPECT_TRUE(isPermutationOfGraphKeys(order, g)) << "n " << n;
    const std::vector<Key> natural = naturalOrdering(g);
    EXPECT_TRUE(isPermutationOfGraphKeys(natural, g));
    EXPECT_TRUE(std::is_sorted(natural.begin(), natural.end()));
  }
}

TEST(Ordering, EmptyGraphGivesEmptyOrder) {
  const FactorGraph g;
  EXPECT_TRUE(colamdOrdering(g).empty());
  EXPECT_TRUE(constrainedOrdering(g, OrderingConstraints{}).empty());
}

TEST(Ordering, IsDeterministicAndIndependentOfInputForm) {
  std::mt19937 rng_a(9), rng_b(9);
  const FactorGraph a = chainWithLandmarks(150, 5, rng_a);
  const FactorGraph b = chainWithLandmarks(150, 5, rng_b);
  const std::vector<Key> first = colamdOrdering(a);
  EXPECT_EQ(first, colamdOrdering(a));
  EXPECT_EQ(first, colamdOrdering(b));
  std::vector<std::vector<Key>> lists;
  for (const auto& f : a) lists.push_back(f->keys());
  EXPECT_EQ(first, colamdOrdering(lists));
  const auto c = OrderingConstraints::firstAndLast(std::vector<Key>{sym::X(3)}, std::vector<Key>{sym::X(149)});
  EXPECT_EQ(constrainedOrdering(a, c), constrainedOrdering(lists, c));
}

TEST(Ordering, ConstrainedGroupsAreRespected) {
  std::mt19937 rng(4);
  const int n = 120;
  const FactorGraph g = chainWithLandmarks(n, 6, rng);
  // Oldest poses first (to marginalize), the newest three last.
  std::vector<Key> first, last;
  for (int i = 0; i < 10; ++i) first.push_back(sym::X(static_cast<std::uint64_t>(i)));
  for (int i = n - 3; i < n; ++i) last.push_back(sym::X(static_cast<std::uint64_t>(i)));
  const std::vector<Key> order = constrainedOrdering(g, OrderingConstraints::firstAndLast(first, last));
  ASSERT_TRUE(isPermutationOfGraphKeys(order, g));
  const std::set<Key> first_set(first.begin(), first.end()), last_set(last.begin(), last.end());
  const std::set<Key> head(order.begin(), order.begin() + static_cast<long>(first.size()));
  const std::set<Key> tail(order.end() - static_cast<long>(last.size()), order.end());
  EXPECT_EQ(head, first_set);
  EXPECT_EQ(tail, last_set);
}

TEST(Ordering, NonContiguousGroupsKeepTheirOrder) {
  std::mt19937 rng(6);
  const FactorGraph g = chainWithLandmarks(60, 3, rng);
  OrderingConstraints c;
  c.default_group = 50;
  for (int i = 0; i < 60; i += 7) c.group[sym::X(static_cast<std::uint64_t>(i))] = 1000;  // last
  c.group[sym::L(0)] = 5;                                                                 // first
  c.group[sym::X(30)] = 5;
  const std::vector<Key> order = constrainedOrdering(g, c);
  ASSERT_TRUE(isPermutationOfGraphKeys(order, g));
  auto groupOf = [&c](Key k) {
    auto it = c.group.find(k);
    return it == c.group.end() ? c.default_group : it->second;
  };
  for (std::size_t i = 0; i + 1 < order.size(); ++i) {
    EXPECT_LE(groupOf(order[i]), groupOf(order[i + 1])) << keyString(order[i]) << " before " << keyString(order[i + 1]);
  }
}

TEST(Ordering, NegativeGroupThrows) {
  FactorGraph g;
  g.emplace<KeysOnlyFactor>(std::vector<Key>{sym::X(0), sym::X(1)});
  OrderingConstraints c;
  c.group[sym::X(1)] = -1;
  EXPECT_THROW((void)constrainedOrdering(g, c), std::invalid_argument);
  OrderingConstraints d;
  d.default_group = -2;
  EXPECT_THROW((void)constrainedOrdering(g, d), std::invalid_argument);
}

// nnz(L) of the block Hessian of g with columns in `order`.
double factorNonzeros(const FactorGraph& g, const std::vector<Key>& order) {
  Values v;
  for (Key k : order) v.insert(k, keySymbol(k) == 'x' ? Variable(Pose3()) : Variable(Vec3::Zero().eval()));
  NormalEquations ne;
  ne.setStructure(g, v, order);
  CholmodContext ctx;
  CholmodFactor factor;
  EXPECT_TRUE(ctx.analyze(ne.hessian(), {}, {}, &factor).ok());
  return factor.factorNonzeros();
}

TEST(Ordering, ColamdReducesFillOnAHubGraph) {
  // Every pose ranges to one anchor: eliminating the anchor first would make
  // the whole pose block dense.
  FactorGraph g;
  const int n = 80;
  for (int i = 0; i < n; ++i) {
    g.emplace<KeysOnlyFactor>(std::vector<Key>{sym::X(static_cast<std::uint64_t>(i)), sym::L(0)});
    if (i + 1 < n) {
      g.emplace<KeysOnlyFactor>(
          std::vector<Key>{sym::X(static_cast<std::uint64_t>(i)), sym::X(static_cast<std::uint64_t>(i + 1))});
    }
  }
  std::vector<Key> hub_first = {sym::L(0)};
  for (int i = 0; i < n; ++i) hub_first.push_back(sym::X(static_cast<std::uint64_t>(i)));
  const double colamd_nnz = factorNonzeros(g, colamdOrdering(g));
  const double hub_first_nnz = factorNonzeros(g, hub_first);
  EXPECT_LT(colamd_nnz, 0.1 * hub_first_nnz) << colamd_nnz << " vs " << hub_first_nnz;
}

}  // namespace
}  // namespace rilo
