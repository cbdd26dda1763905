#pragma once
// A small SVG writer for line and scatter plots (the figures of `rilo
// report`): axes with "nice" or given ticks, optional log10 axes, optional
// equal aspect (top views in metres), grid, title, and a legend. No external
// library; the output is a standalone SVG 1.1 document.
//
// Conventions: a Series is drawn as a polyline through its points (broken at
// every non-finite x or y, so NaN marks a gap) and/or as markers. On a log
// axis, values <= 0 are gaps too. Data outside a fixed axis range is clipped
// to the plot area.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rilo::svg {

enum class Marker { kNone, kCircle, kSquare, kTriangle, kCross };

struct Series {
  std::string label;           ///< legend text; empty: not in the legend
  std::vector<double> x, y;    ///< same length
  std::string color = "#1f77b4";
  double line_width_px = 1.5;  ///< 0: markers only
  bool dashed = false;
  Marker marker = Marker::kNone;
  double marker_size_px = 3.5;  ///< radius (half width) of a marker
};

struct Tick {
  double value = 0.0;
  std::string label;
};

struct Axis {
  std::string label;
  bool log = false;                ///< log10 scale
  std::optional<double> min, max;  ///< unset: the data range plus a small margin
  std::vector<Tick> ticks;         ///< empty: automatic ticks (1-2-5 steps; decades on a log axis)
};

/// kAuto: the inside corner covering the fewest data points (top right on a tie).
enum class LegendPosition { kAuto, kTopRight, kTopLeft, kBottomRight, kBottomLeft, kNone };

struct Plot {
  std::string title;
  Axis x, y;
  int width_px = 720;
  int height_px = 440;
  /// One data unit is as long on x as on y (maps, top views); linear axes only.
  bool equal_aspect = false;
  LegendPosition legend = LegendPosition::kAuto;
  std::vector<Series> series;
};

/// Axis-aligned rectangle in SVG pixels (y grows downwards).
struct Rect {
  double left = 0.0, top = 0.0, width = 0.0, height = 0.0;
  bool contains(double x_px, double y_px, double tol_px = 1e-6) const {
    return x_px >= left - tol_px && x_px <= left + width + tol_px && y_px >= top - tol_px &&
           y_px <= top + height + tol_px;
  }
};

/// Where data lands in the picture: the plot area and the data range it shows.
struct Layout {
  Rect area;
  double x_min = 0.0, x_max = 1.0, y_min = 0.0, y_max = 1.0;  ///< data units (not log10)
  bool x_log = false, y_log = false;

  double toPixelX(double x) const;
  double toPixelY(double y) const;
};

/// Validates `plot` (std::invalid_argument naming the field: sizes, series
/// with x and y of different lengths, inverted or non-positive log ranges) and
/// computes its layout.
Layout layoutOf(const Plot& plot);

/// The SVG document of `plot`. Structure (for tools and tests): the plot area
/// is <rect class="plot-area">, each series a <g class="series"
/// data-label="..."> of <polyline> and marker elements, the legend a <g
/// class="legend"> with one <text> per labelled series.
std::string renderSvg(const Plot& plot);

/// Writes renderSvg(plot) to `file` (std::runtime_error if it cannot).
void writeSvg(const std::filesystem::path& file, const Plot& plot);

/// Up to about `target` ticks covering [lo, hi] at 1, 2 or 5 times a power of
/// ten (all inside [lo, hi]).
std::vector<double> niceTicks(double lo, double hi, int target = 6);

/// Escapes &, <, >, " and ' for XML text and attributes.
std::string xmlEscape(const std::string& text);

}  // namespace rilo::svg
