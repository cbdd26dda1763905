#include "estimation/init/tdoa.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>
#include <utility>

#include "estimation/init/format.h"
#include "estimation/init/tdoa_detail.h"

// locateTdoa in four steps (the header's steps 1-4): the problem from the
// window's samples; hypotheses (closed forms, anchor subsets, beacon starts,
// generic starts and their mirrors); the solution (score, refine the best
// distinct ones, set NLOS anchors aside, fall back on the height band); and
// the judgement (inliers, RMS, PDOP, covariance, the gates).

namespace rilo {

using init_detail::strprintf;
using namespace tdoa_detail;

void TdoaFixParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("TdoaFixParams.") + field + " " + rule);
  };
  if (!(sigma_m > 0.0) || !std::isfinite(sigma_m)) fail("sigma_m", "must be finite and > 0");
  if (!(ultrasonic_sigma_m > 0.0) || !std::isfinite(ultrasonic_sigma_m)) {
    fail("ultrasonic_sigma_m", "must be finite and > 0");
  }
  if (!(ultrasonic_offset_m >= 0.0) || !std::isfinite(ultrasonic_offset_m)) {
    fail("ultrasonic_offset_m", "must be finite and >= 0");
  }
  if (!(ultrasonic_short_side_huber_k > 0.0)) fail("ultrasonic_short_side_huber_k", "must be > 0");
  if (max_hypotheses < 1) fail("max_hypotheses", "must be >= 1");
  if (refine_candidates < 1) fail("refine_candidates", "must be >= 1");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (min_anchors < 4) fail("min_anchors", "must be >= 4 (3 independent differences for 3 unknowns)");
  if (min_measurements < 3) fail("min_measurements", "must be >= 3");
  if (!(inlier_sigmas > 0.0)) fail("inlier_sigmas", "must be > 0");
  if (!(max_rms_m > 0.0)) fail("max_rms_m", "must be > 0");
  if (!(max_pdop > 0.0)) fail("max_pdop", "must be > 0");
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) fail("min_inlier_fraction", "must be in [0, 1]");
  if (!(ambiguity_cost_gap >= 0.0)) fail("ambiguity_cost_gap", "must be >= 0");
  band.validate("TdoaFixParams.band");
}

namespace {

[[noreturn]] void badInput(const std::string& what) { throw std::invalid_argument("locateTdoa: " + what); }

/// The window's samples as a problem, checking every field they reference.
struct Window {
  Problem pr;
  std::map<std::uint32_t, std::vector<double>> us_by_beacon;  ///< ultrasonic ranges per beacon
  double us_sigma = 1.0;  ///< ultrasonic sigma with the receiver's offset (m)
};

void readWindow(std::span<const TdoaSample> tdoa, std::span<const UltrasonicSample> ultrasonic,
                const std::vector<Vec3>& p_w_anchors, const TdoaFixParams& params, Window& w) {
  const std::size_t n_anchors = p_w_anchors.size();
  auto anchorAt = [&](std::uint32_t id, const std::string& field) -> const Vec3& {
    if (id >= n_anchors) {
      badInput(field + " = " + std::to_string(id) + ": unknown anchor id (" + std::to_string(n_anchors) +
               " anchors)");
    }
    if (!p_w_anchors[id].allFinite()) {
      badInput("p_w_anchors[" + std::to_string(id) + "] (" + field + ") is not finite");
    }
    return p_w_anchors[id];
  };
  Problem& pr = w.pr;
  auto& us_by_beacon = w.us_by_beacon;
  pr.params = &params;
  pr.sigma_m = params.sigma_m;
  pr.loss.loss = params.loss ? params.loss : defaultAsymmetricLoss();
  pr.loss.mirror = !pr.loss.loss->isSymmetric();
  w.us_sigma = std::sqrt(params.ultrasonic_sigma_m * params.ultrasonic_sigma_m +
                         params.ultrasonic_offset_m * params.ultrasonic_offset_m / 3.0);
  pr.us_loss.long_side =
      params.ultrasonic_long_side_loss ? params.ultrasonic_long_side_loss : defaultAsymmetricLoss();
  pr.us_loss.short_side_k = params.ultrasonic_short_side_huber_k;
  pr.us_sigma_m = w.us_sigma;

  for (std::size_t i = 0; i < tdoa.size(); ++i) {
    const TdoaSample& s = tdoa[i];
    const std::string at = "tdoa[" + std::to_string(i) + "]";
    if (s.anchor_a == s.anchor_b) badInput(at + ": anchor_a == anchor_b (" + std::to_string(s.anchor_a) + ")");
    const Vec3& a = anchorAt(s.anchor_a, at + ".anchor_a");
    const Vec3& b = anchorAt(s.anchor_b, at + ".anchor_b");
    if (!std::isfinite(s.diff_m)) badInput(at + ".diff_m is not finite");
    if ((a - b).norm() < 1e-9) badInput(at + ": anchor_a and anchor_b are at the same position");
    pr.rows.push_back({a, b, s.diff_m, s.anchor_a, s.anchor_b});
  }
  for (std::size_t j = 0; j < ultrasonic.size(); ++j) {
    const UltrasonicSample& u = ultrasonic[j];
    const std::string at = "ultrasonic[" + std::to_string(j) + "]";
    const Vec3& bpos = anchorAt(u.anchor_id, at + ".anchor_id");
    if (!std::isfinite(u.range_m)) badInput(at + ".range_m is not finite");
    if (u.range_m < 0.0) badInput(at + ".range_m is negative");
    pr.us.push_back({bpos, u.range_m, u.anchor_id});
    us_by_beacon[u.anchor_id].push_back(u.range_m);
  }
}

/// Starting points of the refinement. Sets fix.hypotheses; false (with
/// fix.failure and fix.message) when the anchors cannot determine the position.
struct Hypotheses {
  std::vector<Vec3> candidates;
  bool have_plane = false;   ///< the sources' best-fit plane exists: mirror starts across it
  Vec3 centroid = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
  Vec3 mirror(const Vec3& p) const { return p - 2.0 * (p - centroid).dot(normal) * normal; }
};

bool hypothesize(const PairGraph& graph, const Window& w, const std::vector<Vec3>& p_w_anchors,
                 const TdoaFixParams& params, TdoaFix& fix, Hypotheses& h) {
  std::vector<Vec3>& candidates = h.candidates;
  const auto& us_by_beacon = w.us_by_beacon;
  std::string closed_form_failure;
  auto addClosedForm = [&](const std::vector<int>& members) {
    const std::uint32_t ref = graph.anchors[static_cast<std::size_t>(members[0])];
    std::vector<Vec3> others;
    std::vector<double> d;
    for (std::size_t i = 1; i < members.size(); ++i) {
      const auto k = static_cast<std::size_t>(members[i]);
      others.push_back(p_w_anchors[graph.anchors[k]]);
      d.push_back(graph.D[k] - graph.D[static_cast<std::size_t>(members[0])]);
    }
    const TdoaClosedForm cf = tdoaSphericalIntersection(p_w_anchors[ref], others, d, 0.02);
    for (int c = 0; c < cf.count; ++c) candidates.push_back(cf.p_w[static_cast<std::size_t>(c)]);
    return cf;
  };
  const int m = static_cast<int>(graph.anchors.size());
  if (m >= 4) {
    std::vector<int> all(static_cast<std::size_t>(m));
    std::iota(all.begin(), all.end(), 0);
    const TdoaClosedForm cf = addClosedForm(all);
    if (cf.degenerate) closed_form_failure = cf.failure;
    if (params.consensus) {
      for (const auto& s : anchorSubsets(m, params.max_hypotheses)) addClosedForm({s[0], s[1], s[2], s[3]});
    }
  }
  if (us_by_beacon.size() >= 3) {
    std::vector<Vec3> beacons;
    std::vector<double> ranges;
    for (const auto& [id, r] : us_by_beacon) {
      beacons.push_back(p_w_anchors[id]);
      ranges.push_back(median(r));
    }
    std::array<Vec3, 2> p{};
    const int k = rangeIntersection(beacons, ranges, p);
    for (int i = 0; i < k; ++i) candidates.push_back(p[static_cast<std::size_t>(i)]);
  }
  if (candidates.empty() && !closed_form_failure.empty()) {
    // The anchors cannot determine the position, whatever the data.
    fix.failure = TdoaFixFailure::kDegenerateGeometry;
    fix.message = "no closed-form solution: " + closed_form_failure;
    return false;
  }
  // No closed form for a mix of fewer than 4 connected anchors and beacons
  // (nor when noise leaves the closed form without an admissible root):
  // start on each beacon's sphere straight below it (beacons hang from the
  // ceiling) and from the centroid below.
  for (const auto& [id, r] : us_by_beacon) candidates.push_back(p_w_anchors[id] - Vec3(0.0, 0.0, median(r)));
  fix.hypotheses = static_cast<int>(candidates.size());

  // Generic starts: the centroid of all sources at the band's middle height
  // (1 m below the centroid without a band) and its mirror.
  std::vector<Vec3> sources;
  for (std::uint32_t id : graph.anchors) sources.push_back(p_w_anchors[id]);
  for (const auto& [id, r] : us_by_beacon) sources.push_back(p_w_anchors[id]);
  h.have_plane = bestFitPlane(sources, h.centroid, h.normal);
  if (!h.have_plane) {
    for (const Vec3& s : sources) h.centroid += s;
    if (!sources.empty()) h.centroid /= static_cast<double>(sources.size());
  }
  Vec3 start = h.centroid;
  start.z() = params.band.enabled ? params.band.midZ() : h.centroid.z() - 1.0;
  candidates.push_back(start);
  if (h.have_plane) candidates.push_back(h.mirror(start));
  return true;
}

/// The best solution from the hypotheses: scored, the best distinct ones
/// refined (and the winner's mirror), NLOS anchors set aside and the rest
/// refined again, the height band as a prior where the data say less.
/// Sets fix.second_cost_gap, anchors_rejected and height_from_band.
Solution solve(const PairGraph& graph, const Hypotheses& h, const std::vector<Vec3>& p_w_anchors,
               const TdoaFixParams& params, Window& w, TdoaFix& fix) {
  Problem& pr = w.pr;
  const double us_sigma = w.us_sigma;
  const int m = static_cast<int>(graph.anchors.size());
  const std::vector<Vec3>& candidates = h.candidates;
  // Consensus in anchor space when >= 4 anchors are connected (header, step 3).
  pr.row_used.assign(pr.rows.size(), 1);
  pr.anchor_space = m >= 4;
  if (pr.anchor_space) {
    for (std::size_t k = 0; k < graph.anchors.size(); ++k) {
      pr.pseudo.push_back({p_w_anchors[graph.anchors[k]], graph.D[k], params.sigma_m * graph.sd[k], graph.anchors[k]});
    }
    pr.pseudo_loss.long_side = pr.loss.loss;
    pr.pseudo_loss.short_side_k = 3.0;
  }
  auto stateAt = [&](const Vec3& p) -> Vec4 {
    Vec4 x;
    x << p, pr.anchor_space ? bestOffset(pr, p) : 0.0;
    return x;
  };

  // Score at the first pass's ultrasonic sigma, refine the best distinct ones.
  pr.us_sigma_m = std::max(us_sigma, params.sigma_m);
  std::vector<std::pair<double, Vec4>> scored;
  for (const Vec3& c : candidates) {
    if (!c.allFinite()) continue;
    const Vec4 x = stateAt(c);
    scored.emplace_back(costOf(pr, x), x);
  }
  std::stable_sort(scored.begin(), scored.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<Vec4> starts;
  for (const auto& scored_start : scored) {
    // A named variable, not a structured binding: clang before 16 cannot
    // capture those in the lambda (the fuzzing build, scripts/fuzz.sh).
    const Vec4& x = scored_start.second;
    if (static_cast<int>(starts.size()) >= params.refine_candidates) break;
    const bool distinct = std::none_of(starts.begin(), starts.end(), [&](const Vec4& q) {
      return (q.head<3>() - x.head<3>()).norm() < 0.5;
    });
    if (distinct) starts.push_back(x);
  }
  std::vector<Solution> sols;
  for (const Vec4& x0 : starts) sols.push_back(refine(pr, x0, us_sigma));
  std::size_t best = 0;
  for (std::size_t i = 1; i < sols.size(); ++i) {
    if (sols[i].cost < sols[best].cost) best = i;
  }
  if (h.have_plane) {
    sols.push_back(refine(pr, stateAt(h.mirror(sols[best].p())), us_sigma));
    if (sols.back().cost < sols[best].cost) best = sols.size() - 1;
  }
  Solution s = sols[best];
  for (std::size_t i = 0; i < sols.size(); ++i) {
    if (i == best || (sols[i].p() - s.p()).norm() < 0.5) continue;
    fix.second_cost_gap = std::min(fix.second_cost_gap, sols[i].cost - s.cost);
  }
  // Anchors whose pseudo-range disagrees are NLOS for this window: their rows
  // are set aside; the raw rows of the others refine the position (optimal
  // weighting, sporadic outliers by the robust loss).
  // The gate's sigma is at least one path's noise (sigma_m / sqrt(2)): the
  // pair medians carry biases of that order when single rows are NLOS.
  std::set<std::uint32_t> rejected;
  if (pr.anchor_space) {
    for (const AnchorObs& o : pr.pseudo) {
      const double gate = params.inlier_sigmas * std::max(o.sigma_m, params.sigma_m / std::sqrt(2.0));
      const double e = o.D_m - (s.p() - o.a).norm() - s.x(3);
      if (params.consensus && !(std::abs(e) <= gate)) rejected.insert(o.id);
    }
    for (std::size_t i = 0; i < pr.rows.size(); ++i) {
      pr.row_used[i] = !rejected.contains(pr.rows[i].id_a) && !rejected.contains(pr.rows[i].id_b);
    }
    pr.anchor_space = false;
    s = refine(pr, s.x, us_sigma);
  }
  fix.anchors_rejected = static_cast<int>(rejected.size());
  // Height from the band when the measurements know less about it (header).
  if (params.band.enabled) {
    const double sigma_band = (params.band.maxZ() - params.band.minZ()) / std::sqrt(12.0);
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(s.H_data);
    double sigma_z_data = std::numeric_limits<double>::infinity();
    if (eig.eigenvalues().minCoeff() > 1e-12 * std::max(1.0, eig.eigenvalues().maxCoeff())) {
      const Mat3 cov =
          eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
      sigma_z_data = std::sqrt(std::max(0.0, cov(2, 2)));
    }
    if (!(sigma_z_data <= sigma_band)) {
      pr.height_prior = true;
      pr.height_prior_z = params.band.midZ();
      pr.height_prior_sigma = sigma_band;
      Vec4 x0 = s.x;
      x0(2) = std::clamp(x0(2), params.band.minZ(), params.band.maxZ());
      s = refine(pr, x0, us_sigma);
      fix.height_from_band = true;
    }
  }
  pr.us_sigma_m = us_sigma;
  return s;
}

/// Quality of the solution (inliers, RMS, PDOP, covariance) and the gates a
/// fix must pass; sets fix.valid or fix.failure, and fix.message.
void judge(const Solution& s, const Window& w, const std::vector<Vec3>& p_w_anchors, const TdoaFixParams& params,
           int m, int needed, TdoaFix& fix) {
  const Problem& pr = w.pr;
  const double us_sigma = w.us_sigma;
  // Quality: inliers, used anchors, RMS.
  std::set<std::uint32_t> used, used_beacons;
  double sum2 = 0.0;
  int rows_considered = 0, inliers_considered = 0;
  for (std::size_t i = 0; i < pr.rows.size(); ++i) {
    const Row& o = pr.rows[i];
    const double r = tdoaResidual(o, fix.p_w_tag, pr.sigma_m);
    rows_considered += pr.row_used[i] ? 1 : 0;
    if (!(std::abs(r) <= params.inlier_sigmas)) continue;
    inliers_considered += pr.row_used[i] ? 1 : 0;
    ++fix.inliers;
    sum2 += r * r;
    used.insert(o.id_a);
    used.insert(o.id_b);
  }
  if (fix.inliers > 0) fix.rms_m = params.sigma_m * std::sqrt(sum2 / fix.inliers);
  fix.anchors_used = static_cast<int>(used.size());
  double us_sum2 = 0.0;
  for (const UsRow& u : pr.us) {
    const double r = usResidual(u, fix.p_w_tag, us_sigma);
    if (!(std::abs(r) <= params.inlier_sigmas)) continue;
    ++fix.ultrasonic_inliers;
    us_sum2 += r * r;
    used_beacons.insert(u.id);
  }
  if (fix.ultrasonic_inliers > 0) fix.ultrasonic_rms_m = us_sigma * std::sqrt(us_sum2 / fix.ultrasonic_inliers);

  // PDOP as in GNSS: rows [u^T 1] for anchors (the unknown common range is
  // the clock), [u^T 0] for beacons.
  Mat4 Q = Mat4::Zero();
  for (std::uint32_t id : used) {
    Vec4 row;
    row << unitFrom(p_w_anchors[id], fix.p_w_tag), 1.0;
    Q.noalias() += row * row.transpose();
  }
  for (std::uint32_t id : used_beacons) {
    Vec4 row;
    row << unitFrom(p_w_anchors[id], fix.p_w_tag), 0.0;
    Q.noalias() += row * row.transpose();
  }
  if (used.empty()) Q(3, 3) = 1.0;  // no TDoA: no common range to solve for
  auto pdopOf = [](const Mat4& q, Vec3* weakest) {
    const Eigen::SelfAdjointEigenSolver<Mat4> eig(q);
    if (!(eig.eigenvalues()(0) > 1e-9 * std::max(1.0, eig.eigenvalues()(3)))) {
      if (weakest) *weakest = eig.eigenvectors().col(0).head<3>();
      return std::numeric_limits<double>::infinity();
    }
    const Mat4 cov =
        eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
    return std::sqrt(std::max(0.0, cov.topLeftCorner<3, 3>().trace()));
  };
  Vec3 weakest = Vec3::Zero();
  if (fix.height_from_band) Q(2, 2) += 1.0;  // the band stands in for the height
  fix.pdop = pdopOf(Q, &weakest);
  const Eigen::SelfAdjointEigenSolver<Mat3> eigH(Mat3(s.H.topLeftCorner<3, 3>()));  // row space: c is not coupled
  if (eigH.eigenvalues().minCoeff() > 1e-12) {
    fix.cov_p = eigH.eigenvectors() * eigH.eigenvalues().cwiseInverse().asDiagonal() * eigH.eigenvectors().transpose();
    fix.sigma_p_m = std::sqrt(std::max(0.0, fix.cov_p.trace()));
  }

  const Vec3& p = fix.p_w_tag;
  std::string summary = strprintf("p=(%.2f, %.2f, %.2f) m", p.x(), p.y(), p.z()) +
                        strprintf(", %d/%d inliers, %d anchors, rms %.3f m", fix.inliers, fix.measurements,
                                  fix.anchors_used, fix.rms_m);
  if (fix.ultrasonic_ranges > 0) {
    summary += strprintf(", ultrasonic %d/%d inliers from %d beacons, rms %.3f m", fix.ultrasonic_inliers,
                         fix.ultrasonic_ranges, static_cast<int>(used_beacons.size()), fix.ultrasonic_rms_m);
  }
  if (fix.anchors_rejected > 0) {
    summary += strprintf(", %d NLOS anchor%s set aside", fix.anchors_rejected, fix.anchors_rejected > 1 ? "s" : "");
  }
  summary += strprintf(", pdop %.1f, sigma %.3f m", fix.pdop, fix.sigma_p_m);
  if (fix.height_from_band) summary += ", height mostly from the band";

  const int info_used = std::max(0, fix.anchors_used - 1) + static_cast<int>(used_beacons.size());
  const bool have_rows = fix.measurements > 0;
  // Rows of the anchors set aside are not counted against the fix (their
  // number is judged at the anchor level).
  const double inlier_fraction =
      have_rows ? static_cast<double>(inliers_considered) / static_cast<double>(std::max(1, rows_considered))
                : static_cast<double>(fix.ultrasonic_inliers) / static_cast<double>(std::max(1, fix.ultrasonic_ranges));
  const double anchor_fraction =
      m > 0 ? static_cast<double>(m - fix.anchors_rejected) / static_cast<double>(m) : 1.0;
  const double rms = have_rows ? fix.rms_m : fix.ultrasonic_rms_m;
  auto fail = [&](TdoaFixFailure why, const std::string& text) {
    fix.failure = why;
    fix.message = text;
  };
  if (!std::isfinite(s.cost) || !s.x.allFinite()) {
    fail(TdoaFixFailure::kDiverged, "TDoA refinement diverged");
  } else if (info_used < needed) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: %d anchors and %d beacons with inliers, need %d anchors; ", fix.anchors_used,
                   static_cast<int>(used_beacons.size()), params.min_anchors) + summary);
  } else if (anchor_fraction < params.min_inlier_fraction) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: %d of %d anchors disagree (NLOS?); ", fix.anchors_rejected, m) + summary);
  } else if (inlier_fraction < params.min_inlier_fraction) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: only %.0f%% inliers; ", 100.0 * inlier_fraction) + summary);
  } else if (!(rms <= params.max_rms_m)) {
    fail(TdoaFixFailure::kLargeResiduals, "poor fix: residual RMS too large; " + summary);
  } else if (!(fix.pdop <= params.max_pdop)) {
    std::string why = "poor fix: anchor geometry (PDOP)";
    if (std::abs(weakest.z()) > 0.9) why += ", the height is unobservable (tag in the anchors' plane?)";
    fail(TdoaFixFailure::kPoorGeometry, why + "; " + summary);
  } else if (fix.mirror_ambiguous) {
    fail(TdoaFixFailure::kAmbiguous,
         strprintf("ambiguous fix: a second solution costs only %.2f more; ", fix.second_cost_gap) + summary);
  } else if (!params.band.contains(p.z(), 3.0 * params.band.sigma_m)) {
    fail(TdoaFixFailure::kOutsideHeightBand,
         strprintf("poor fix: height %.2f m outside the height band; ", p.z()) + summary);
  } else {
    fix.valid = true;
    fix.message = summary;
  }
}

}  // namespace

TdoaFix locateTdoa(std::span<const TdoaSample> tdoa, std::span<const UltrasonicSample> ultrasonic, std::int64_t t_ns,
                   const std::vector<Vec3>& p_w_anchors, const TdoaFixParams& params) {
  params.validate();
  Window w;
  readWindow(tdoa, ultrasonic, p_w_anchors, params, w);
  const Problem& pr = w.pr;

  TdoaFix fix;
  fix.t_ns = t_ns;
  fix.measurements = static_cast<int>(pr.rows.size());
  fix.ultrasonic_ranges = static_cast<int>(pr.us.size());
  fix.beacons_heard = static_cast<int>(w.us_by_beacon.size());
  const PairGraph graph = buildPairGraph(pr.rows);
  fix.anchors_heard = graph.anchors_total;

  // Enough information? Each connected group of anchors gives (size - 1)
  // independent differences; each beacon one range.
  const int needed = params.min_anchors - 1;
  const int independent = graph.anchors_total - graph.components;
  if (independent + fix.beacons_heard < needed) {
    fix.failure = TdoaFixFailure::kTooFewAnchors;
    fix.message = strprintf("%d anchors heard (%d independent differences) and %d ultrasonic beacons, need %d anchors",
                            fix.anchors_heard, independent, fix.beacons_heard, params.min_anchors);
    if (fix.beacons_heard == 0) fix.message += " (each ultrasonic beacon stands in for one)";
    return fix;
  }
  if (fix.measurements + fix.ultrasonic_ranges < params.min_measurements) {
    fix.failure = TdoaFixFailure::kTooFewAnchors;
    fix.message = strprintf("%d measurements in the window, need %d", fix.measurements + fix.ultrasonic_ranges,
                            params.min_measurements);
    return fix;
  }

  Hypotheses h;
  if (!hypothesize(graph, w, p_w_anchors, params, fix, h)) return fix;
  const Solution s = solve(graph, h, p_w_anchors, params, w, fix);
  fix.p_w_tag = s.p();
  fix.cost = s.cost;
  fix.mirror_ambiguous = fix.second_cost_gap < params.ambiguity_cost_gap;
  judge(s, w, p_w_anchors, params, static_cast<int>(graph.anchors.size()), needed, fix);
  return fix;
}

}  // namespace rilo
