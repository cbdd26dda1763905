#pragma once
// What the deployment knows about the tag's height: a soft band above the
// floor (architecture "Known hard cases": anchors at similar heights leave the
// height weakly observable and the mirror solution on the other side of the
// anchor plane fits the ranges too). Used by the initializer as a one-sided
// penalty: zero inside the band, (z - bound) / sigma outside it.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "estimation/measurements/anchor_box.h"

namespace rilo {

struct HeightBand {
  bool enabled = true;
  double floor_z_m = 0.0;     ///< floor height in the world frame (m, z up)
  // A wearable on a person who walks, stands or sits: chest height when
  // seated (~1.0 m) to head height when standing (~1.8 m), with a margin.
  double min_height_m = 0.9;  ///< lowest tag height above the floor (m)
  double max_height_m = 1.9;  ///< highest tag height above the floor (m)
  double sigma_m = 0.1;       ///< softness of the band's edges (m)
  // How the height is held inside the band (range_imu_graph_stream.h; issue
  // 36: without them the far ranges' unremoved NLOS excess held the foreign
  // offices' tag 0.5 m low). Both need the band enabled.
  /// A two-way range speaks to the height only by its vertical lever
  /// (RangeImuGraphStream::verticalWeightOf).
  bool range_lever = true;
  /// Each state's height is held towards the carry height with this sigma
  /// per sqrt(s) of data (m; 0: off): the weight per second is that of a
  /// sigma of hold_sigma_m.
  double hold_sigma_m = 0.5;
  /// The carry height is learnt while tracking (carry_height.h), else the
  /// band's middle; evidence fades over carry_memory_s (s).
  bool learn_carry_height = false;
  double carry_memory_s = 120.0;

  static HeightBand off() {
    HeightBand b;
    b.enabled = false;
    return b;
  }

  double minZ() const { return floor_z_m + min_height_m; }
  double maxZ() const { return floor_z_m + max_height_m; }
  double midZ() const { return floor_z_m + 0.5 * (min_height_m + max_height_m); }

  /// Whitened one-sided residual of a tag height z (0 inside the band or when disabled).
  double residual(double z_m) const {
    if (!enabled) return 0.0;
    if (z_m < minZ()) return (z_m - minZ()) / sigma_m;
    if (z_m > maxZ()) return (z_m - maxZ()) / sigma_m;
    return 0.0;
  }
  /// d residual / d z.
  double derivative(double z_m) const {
    if (!enabled || (z_m >= minZ() && z_m <= maxZ())) return 0.0;
    return 1.0 / sigma_m;
  }
  bool contains(double z_m, double margin_m = 0.0) const {
    return !enabled || (z_m >= minZ() - margin_m && z_m <= maxZ() + margin_m);
  }

  /// Whether the band's floor fits the surveyed anchors, i.e. the anchors'
  /// frame has its floor where the band assumes (recordings in a frame with
  /// another origin, such as a headset's first pose, would be pulled to a
  /// wrong height): none more than 0.5 m below the floor and their median
  /// 1-6 m above it, as wall, ceiling or desk mounts are. Placeholders of
  /// unused ids (isAnchorPlaceholder, anchor_box.h) are ignored.
  template <class Vec3List>
  bool plausibleFor(const Vec3List& p_w_anchors) const {
    std::vector<double> heights;
    for (const auto& p : p_w_anchors) {
      if (isAnchorPlaceholder(p)) continue;
      heights.push_back(p.z() - floor_z_m);
    }
    if (heights.empty()) return false;
    std::sort(heights.begin(), heights.end());
    const double median = heights[heights.size() / 2];
    return heights.front() >= -0.5 && median >= 1.0 && median <= 6.0;
  }

  /// Throws std::invalid_argument naming the field.
  void validate(const std::string& where) const {
    if (!enabled) return;
    if (!(max_height_m > min_height_m)) throw std::invalid_argument(where + ".max_height_m must be > min_height_m");
    if (!(sigma_m > 0.0)) throw std::invalid_argument(where + ".sigma_m must be > 0");
    if (!std::isfinite(floor_z_m)) throw std::invalid_argument(where + ".floor_z_m must be finite");
    if (!(hold_sigma_m >= 0.0) || std::isinf(hold_sigma_m)) {
      throw std::invalid_argument(where + ".hold_sigma_m must be >= 0 and finite");
    }
    if (!(carry_memory_s > 0.0)) throw std::invalid_argument(where + ".carry_memory_s must be > 0");
  }
};

}  // namespace rilo
