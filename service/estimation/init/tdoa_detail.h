#pragma once
// The internals of locateTdoa (tdoa.cpp) that its files share: the problem
// (TDoA rows, ultrasonic ranges, the pair graph's pseudo-ranges) and its robust
// Levenberg-Marquardt (tdoa_problem.cpp), and the sources of its hypotheses
// (tdoa_hypotheses.cpp: the pair graph, ultrasonic trilateration, best-fit
// plane, anchor subsets). Not an interface: only init/tdoa*.cpp include it.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "estimation/init/range_loss.h"
#include "estimation/init/tdoa.h"
#include "estimation/noise/robust_loss.h"
#include "math/types.h"

namespace rilo::tdoa_detail {

using MatX3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;
using VecX = Eigen::VectorXd;

struct Row {
  Vec3 a;             ///< reference anchor (m)
  Vec3 b;             ///< other anchor (m)
  double diff_m;      ///< |p - b| - |p - a| measured (m)
  std::uint32_t id_a;
  std::uint32_t id_b;
};

struct UsRow {
  Vec3 beacon;        ///< ultrasonic beacon (m)
  double range_m;
  std::uint32_t id;
};

/// Loss of the whitened TDoA residual; asymmetric losses mirrored (either
/// anchor of a row can be the blocked one).
struct TdoaLoss {
  RobustLossPtr loss;
  bool mirror = false;
  double rho(double r) const { return loss->loss(mirror ? std::abs(r) : r); }
  double weight(double r) const { return loss->weight(mirror ? std::abs(r) : r); }
};

/// Pseudo-range of an anchor of the pair graph (anchor space):
///   D_k = |p - A_k| + c + e_k,
/// c the unknown common range (the receiver clock of GNSS), e_k >= 0 anchor
/// k's NLOS excess over the window.
struct AnchorObs {
  Vec3 a;             ///< anchor (m)
  double D_m;         ///< D_k - D_root from the pair graph (m)
  double sigma_m;     ///< its std-dev (m)
  std::uint32_t id;
};

using Vec4 = Eigen::Vector4d;
using Mat4 = Eigen::Matrix4d;

/// State x = (p, c): tag position (m) and the common range c (m; anchor space
/// only, held fixed in row space).
struct Problem {
  std::vector<Row> rows;
  std::vector<char> row_used;      ///< row space: the row is in the cost (touches no rejected anchor)
  std::vector<AnchorObs> pseudo;   ///< anchor space observations
  bool anchor_space = false;       ///< cost over `pseudo` with (p, c), else over `rows` with p
  std::vector<UsRow> us;
  TdoaLoss loss;                   ///< of the rows
  InitRangeLoss pseudo_loss;       ///< of the pseudo-ranges: NLOS tail on the long side
  InitRangeLoss us_loss;
  double sigma_m = 1.0;
  double us_sigma_m = 1.0;   ///< ultrasonic sigma of the current pass (m)
  const TdoaFixParams* params = nullptr;
  /// Gaussian height prior (the band as N(mid, width^2 / 12)) when the
  /// geometry leaves the height to the band.
  bool height_prior = false;
  double height_prior_z = 0.0;
  double height_prior_sigma = 1.0;
};

struct Solution {
  Vec4 x = Vec4::Zero();
  double cost = std::numeric_limits<double>::infinity();
  Mat4 H = Mat4::Zero();       ///< robust-weighted normal matrix at x (whitened)
  Mat3 H_data = Mat3::Zero();  ///< position information of the measurements alone
  Vec3 p() const { return x.head<3>(); }
};

/// D_k - D_root of the largest connected component of the pair graph.
struct PairGraph {
  std::vector<std::uint32_t> anchors;  ///< component anchor ids; anchors[0] is the root
  std::vector<double> D;               ///< D_k - D_root (m), same order
  std::vector<double> sd;              ///< std-dev of D_k in row sigmas, without the common offset
  int anchors_total = 0;               ///< distinct anchors over all rows
  int components = 0;
};

double tdoaResidual(const Row& o, const Vec3& p, double sigma_m);

double usResidual(const UsRow& u, const Vec3& p, double sigma_m);

double pseudoResidual(const AnchorObs& o, const Vec4& x);

double costOf(const Problem& pr, const Vec4& x);

/// Unit vector from `anchor` to p (zero on the anchor).
Vec3 unitFrom(const Vec3& anchor, const Vec3& p);

/// Robust-weighted Gauss-Newton system at x: H dx = -g. H_data: the position
/// block of the measurements alone (no band, no height prior).
void linearize(const Problem& pr, const Vec4& x, Mat4& H, Vec4& g, Mat3* H_data = nullptr);

/// Levenberg-Marquardt from x0 at the problem's current ultrasonic sigma.
Solution levenbergMarquardt(const Problem& pr, const Vec4& x0);

/// Both passes: ultrasonic first at the TDoA sigma (so that a start decimetres
/// off still feels them), then at their own.
Solution refine(Problem& pr, const Vec4& x0, double us_sigma_final);

/// Anchor space: the common range c that best explains the pseudo-ranges at
/// p (tried at every anchor's own value: the clean anchors agree on one).
double bestOffset(const Problem& pr, const Vec3& p);

double median(std::vector<double> v);

PairGraph buildPairGraph(const std::vector<Row>& rows);

/// Ultrasonic trilateration (IMU-Ultrasonic-UWB paper, eq. 8, sphere
/// subtraction): 2 V_j^T x = rho_0^2 + |V_j|^2 - rho_j^2 with x = p - U_0.
/// Coplanar beacons (the ceiling): in-plane part by least squares,
/// out-of-plane +-t.
int rangeIntersection(const std::vector<Vec3>& beacons, const std::vector<double>& ranges, std::array<Vec3, 2>& out);

/// Best-fit plane (centroid, unit normal with n.z >= 0) of points; false for < 3.
bool bestFitPlane(const std::vector<Vec3>& pts, Vec3& centroid, Vec3& normal);

double binomial(int n, int k);

/// 4-anchor subsets of {0..m-1}: all of them (lexicographic) up to `max`,
/// else `max` random ones from a fixed seed (deterministic fixes).
std::vector<std::array<int, 4>> anchorSubsets(int m, int max);

/// makeRangeLoss("asymmetric") with its default parameters. Its whitened
/// NLOS scale is the IQR heuristic (1.349, whatever sigma is), so one
/// instance serves every sigma; built once because its density table takes
/// tens of milliseconds.
RobustLossPtr defaultAsymmetricLoss();

}  // namespace rilo::tdoa_detail
