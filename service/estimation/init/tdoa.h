#pragma once
// Position of the UWB tag from a short window of TDoA measurements, plus
// optional ultrasonic ranges (IMU-Ultrasonic-UWB paper, Sec. III-B: spherical intersection,
// ultrasonic-enhanced initialization, Huber-type robust loss). The TDoA
// counterpart of multilateration.h: no prior knowledge of the position,
// the window is one position (no velocity is fitted; a slowly moving device
// blurs the fix by its motion over the window).
//
// Measurement: diff_m = |p - A_b| - |p - A_a| (sensors/samples.h), the reference
// anchor a varying from row to row (TDoA3-like). Residual r = (diff - h(p)) /
// sigma; r > 0 is a late b (NLOS on b), r < 0 a late a (tdoa_factor.h).
//
// 1. Mixed references -> one reference (pair graph). Every row is an edge
//    D_b - D_a = diff of the anchors' unknown ranges D_k = |p - A_k|. Per
//    unordered pair the median of its rows (sporadic multipath outliers), then
//    D_k - D_root by weighted least squares over the connected pair graph
//    (weights 1 / variance of the pair's median; root = the anchor with most
//    rows), with the sd of each D_k from the pseudo-inverse of the graph's
//    Laplacian. A blocked anchor k (NLOS excess e on its path) enters every
//    pair it is in with the same sign, so it biases D_k by e and leaves the
//    others alone: the conversion keeps NLOS per anchor.
// 2. Closed form: spherical intersection (Smith & Abel 1987; the IMU-Ultrasonic-UWB paper's
//    eq. 4-7 subtract the reference sphere from the others). With x = p - A_r,
//    B_i = A_i - A_r, R = |x| and d_i = D_i - D_r:
//        2 B_i^T x + 2 d_i R = |B_i|^2 - d_i^2                         (linear in x, R)
//    Least squares in x for a given R gives x(R) = x0 - R x1, and |x(R)|^2 = R^2
//    is a quadratic in R whose admissible roots (R >= 0, R + d_i >= 0) are the
//    candidates. Rows are then re-weighted by 1 / (R + d_i) (the equation
//    error of row i is 2 (R + d_i) times the error of d_i, as in Chan's
//    two-step) and the solve repeated. With >= 4 differences the unconstrained
//    solve in (x, R) is one more candidate. Anchors coplanar (all at one
//    height, or any planar subset): the rows only see the in-plane part u of x,
//    so (u, R) is solved jointly (>= 3 differences) and the out-of-plane part is
//    t = +-sqrt(R^2 - |u|^2): two mirror candidates. Why this form: it works
//    from the minimal 4 anchors (needed for consensus), keeps both roots for the
//    height band / ultrasonic to choose, and handles the common coplanar
//    ceiling installation, where Chan's 5-anchor first step is singular.
// 3. Consensus in anchor space (RANSAC-like with MSAC scoring, >= 4 connected
//    anchors): hypotheses from every 4-anchor subset of the pair graph
//    (exhaustive up to max_hypotheses subsets, then a fixed-seed random
//    sample), the all-anchor closed form, the ultrasonic trilateration (IMU-Ultrasonic-UWB paper,
//    eq. 8, same sphere subtraction, coplanar ceiling beacons giving a mirror
//    pair) and the centroid at the band's middle height. Each is scored, and
//    the best few distinct ones refined (Levenberg-Marquardt, IRLS weights),
//    on the D_k as pseudo-ranges with a common unknown offset c (GNSS's
//    clock): D_k = |p - A_k| + c + e_k, e_k >= 0 anchor k's NLOS excess, so
//    the range loss applies as is (NLOS tail on the long side). Why anchor
//    space: a blocked anchor is ONE outlier there however many rows it is in,
//    while in row space the rows of two blocked anchors of a TDoA3 ring are
//    half the rows and cut the ring into arcs that a wrong position fits as
//    well (seen in tests: 0.8 m errors). The lowest cost wins; the mirror of
//    the winner across the anchors' best-fit plane is refined too, and a
//    distinct solution within ambiguity_cost_gap makes the fix ambiguous (as
//    in the multilateration). Anchors whose pseudo-range misses by more than
//    inlier_sigmas (sd at least sigma_m / sqrt(2), one path's noise) are NLOS
//    for the window and their rows set aside (anchors_rejected). Fewer than 4
//    connected anchors (made up for by beacons): the same in row space.
// 4. Refinement on the raw rows (optimal weighting, sporadic outliers):
//    LM from the consensus solution, loss on the whitened TDoA residual
//    (default: the Ranging-IMU Fusion paper's asymmetric NLOS loss mirrored, rho(|r|), since
//    either anchor of a row can be blocked; a symmetric loss such as Huber,
//    the IMU-Ultrasonic-UWB paper's eq. 9, is used as is), ultrasonic ranges as range residuals
//    with range_loss.h (heavy tail for long reflections, Huber short
//    side), the height band as a soft one-sided prior. Ultrasonic ranges are
//    cm-accurate, so far from the solution their heavy-tailed loss would
//    ignore them: each LM runs a first pass with them at the TDoA sigma, a
//    second at their own.
// Quality: inliers (|r| <= inlier_sigmas), distinct anchors with an inlier
// row, inlier RMS, PDOP of the used anchors as in GNSS (rows [u_k^T 1]: the
// unknown common range of TDoA plays the receiver clock; ultrasonic rows
// [u_j^T 0]), the position covariance H^-1 of the robust-weighted normal
// matrix at the solution (whitened: trusts sigma_m).
// Height from the band: when the measurements say less about the height than
// the band does (vertical sigma of the measurements alone above the band's
// width / sqrt(12): tag in the plane of coplanar anchors, or far below
// near-coplanar ceiling anchors), NLOS biases slide the height along the weak
// direction to the band's edge. The fix is then refined once more with the
// band as a Gaussian prior N(middle, width^2 / 12) on the height
// (height_from_band; the PDOP counts the band as a vertical row).
// The lever arms are ignored: this is the UWB antenna's position; the
// ultrasonic receiver is taken to be there too, its unknown offset
// (orientation unknown) adding ultrasonic_offset_m^2 / 3 to the range variance.
#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "estimation/measurements/height_band.h"
#include "estimation/noise/robust_loss.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

struct TdoaFixParams {
  double sigma_m = 0.15;                 ///< LOS std-dev of one range difference (m)
  /// Loss of the whitened TDoA residual; null: the asymmetric range loss at
  /// sigma_m (makeRangeLoss "asymmetric"). An asymmetric loss is mirrored
  /// (rho(|r|)), a symmetric one used as is.
  RobustLossPtr loss;
  double ultrasonic_sigma_m = 0.03;      ///< LOS ultrasonic range std-dev (m)
  double ultrasonic_offset_m = 0.0;      ///< |receiver - UWB antenna| on the body (m), direction unknown
  /// Loss of too-long ultrasonic ranges (reflections); null: the asymmetric
  /// range loss at the ultrasonic sigma.
  RobustLossPtr ultrasonic_long_side_loss;
  double ultrasonic_short_side_huber_k = 3.0;  ///< Huber threshold of too-short ultrasonic ranges (sigmas)
  HeightBand band;                       ///< tag height band (soft)
  /// Hypotheses from 4-anchor subsets and NLOS anchors set aside; false: the
  /// all-anchor closed form and the robust loss only.
  bool consensus = true;
  int max_hypotheses = 200;              ///< 4-anchor subsets tried at most (all of them up to this count)
  int refine_candidates = 4;             ///< best distinct hypotheses refined by LM
  int max_iterations = 50;               ///< LM iterations per pass
  int min_anchors = 4;                   ///< anchors needed (each ultrasonic beacon stands in for one)
  int min_measurements = 6;              ///< TDoA rows plus ultrasonic ranges needed
  double inlier_sigmas = 3.0;            ///< |r| <= this many sigmas is an inlier
  double max_rms_m = 0.5;                ///< inlier TDoA residual RMS above this: poor fix (m)
  double max_pdop = 15.0;                ///< PDOP above this: poor geometry
  double min_inlier_fraction = 0.5;      ///< of the TDoA rows (of the ultrasonic ranges without TDoA)
  double ambiguity_cost_gap = 2.0;       ///< a distinct second solution closer in cost than this is ambiguous

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Why a fix is not valid (TdoaFix::message says it in words with numbers).
enum class TdoaFixFailure {
  kNone,
  kTooFewAnchors,        ///< not enough distinct anchors / beacons / rows in the window
  kDegenerateGeometry,   ///< the closed form found no solution (collinear anchors, inconsistent rows)
  kDiverged,             ///< the refinement produced a non-finite result
  kTooFewInliers,        ///< too few rows agree with the solution (anchors or fraction)
  kLargeResiduals,       ///< inlier RMS above max_rms_m
  kPoorGeometry,         ///< PDOP above max_pdop (e.g. tag in the plane of coplanar anchors, no band)
  kAmbiguous,            ///< a distinct second solution fits almost as well (mirror without band)
  kOutsideHeightBand,    ///< the solution's height is outside the band
};

struct TdoaFix {
  bool valid = false;
  TdoaFixFailure failure = TdoaFixFailure::kNone;
  std::string message;          ///< quality summary, or why the fix is not valid
  std::int64_t t_ns = 0;        ///< fix time (given by the caller)
  Vec3 p_w_tag = Vec3::Zero();  ///< antenna position (m)
  Mat3 cov_p = Mat3::Constant(std::numeric_limits<double>::infinity());  ///< position covariance (m^2)
  int anchors_heard = 0;        ///< distinct anchors in the TDoA rows
  int anchors_used = 0;         ///< distinct anchors with at least one inlier row
  int anchors_rejected = 0;     ///< anchors whose pseudo-range disagreed (NLOS over the window), rows set aside
  int measurements = 0;         ///< TDoA rows
  int inliers = 0;              ///< TDoA inlier rows
  int beacons_heard = 0;        ///< distinct ultrasonic beacons
  int ultrasonic_ranges = 0;
  int ultrasonic_inliers = 0;
  int hypotheses = 0;           ///< closed-form candidates scored
  double rms_m = std::numeric_limits<double>::infinity();             ///< TDoA inlier residual RMS (m)
  double ultrasonic_rms_m = std::numeric_limits<double>::infinity();  ///< ultrasonic inlier residual RMS (m)
  double pdop = std::numeric_limits<double>::infinity();              ///< of the used anchors and beacons
  double sigma_p_m = std::numeric_limits<double>::infinity();         ///< sqrt(trace(cov_p)) (m)
  double cost = std::numeric_limits<double>::infinity();  ///< final robust cost of the rows (whitened, ~chi^2/2)
  /// Best distinct other solution's cost minus the winner's, at the
  /// consensus stage (anchor space with >= 4 connected anchors).
  double second_cost_gap = std::numeric_limits<double>::infinity();
  bool mirror_ambiguous = false;
  bool height_from_band = false;  ///< the geometry left z (nearly) unobservable: z mostly from the band's prior
};

/// Fix from `tdoa` rows and `ultrasonic` ranges of one window. Anchor ids of
/// both (UWB anchors and ultrasonic beacons, one id space as in a
/// recording's anchors.csv) index `p_w_anchors` (m, world).
/// Throws std::invalid_argument naming the field for malformed input: an
/// unknown anchor id, anchor_a == anchor_b, a non-finite difference or range,
/// a negative range, a non-finite referenced anchor position, two anchors of a
/// row at the same position, or invalid params. Bad data (outliers, too few
/// anchors, poor geometry) is reported in TdoaFix, never thrown.
TdoaFix locateTdoa(std::span<const TdoaSample> tdoa, std::span<const UltrasonicSample> ultrasonic, std::int64_t t_ns,
                   const std::vector<Vec3>& p_w_anchors, const TdoaFixParams& params);

/// Candidates of the spherical-intersection closed form (step 2 above).
struct TdoaClosedForm {
  int count = 0;                   ///< candidates in p_w (0-3)
  std::array<Vec3, 3> p_w{};       ///< candidate positions (m)
  bool planar = false;             ///< anchors coplanar: candidates 0, 1 mirror each other across their plane
  bool degenerate = false;         ///< count == 0 because of the anchors' geometry (collinear), not the data
  std::string failure;             ///< why count == 0
};

/// Closed form for reference anchor p_w_ref and anchors p_w_anchors[i] with
/// d_m[i] = |p - A_i| - |p - A_ref| (same length, >= 3 anchors). Anchors are
/// coplanar (with the reference) when the smallest singular value of their
/// offsets is below planar_tol times the largest.
TdoaClosedForm tdoaSphericalIntersection(const Vec3& p_w_ref, std::span<const Vec3> p_w_anchors,
                                         std::span<const double> d_m, double planar_tol = 1e-3);

}  // namespace rilo
