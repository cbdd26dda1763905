#pragma once
// What the deployment knows about the tag's height: a soft band above the
// floor (architecture "Known hard cases": anchors at similar heights leave the
// height weakly observable and the mirror solution on the other side of the
// anchor plane fits the ranges too). Used by the initializer as a one-sided
// penalty: zero inside the band, (z - bound) / sigma outside it.
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

struct HeightBand {
  bool enabled = true;
  double floor_z_m = 0.0;     ///< floor height in the world frame (m, z up)
  double min_height_m = 0.5;  ///< lowest tag height above the floor (m)
  double max_height_m = 2.0;  ///< highest tag height above the floor (m)
  double sigma_m = 0.1;       ///< softness of the band's edges (m)

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

  /// Throws std::invalid_argument naming the field.
  void validate(const std::string& where) const {
    if (!enabled) return;
    if (!(max_height_m > min_height_m)) throw std::invalid_argument(where + ".max_height_m must be > min_height_m");
    if (!(sigma_m > 0.0)) throw std::invalid_argument(where + ".sigma_m must be > 0");
    if (!std::isfinite(floor_z_m)) throw std::invalid_argument(where + ".floor_z_m must be finite");
  }
};

}  // namespace rilo
