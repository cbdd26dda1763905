#include "evaluation/svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <utility>

namespace rilo::svg {
namespace {

constexpr double kMarginLeftPx = 72.0;
constexpr double kMarginRightPx = 20.0;
constexpr double kMarginTopPx = 16.0;
constexpr double kTitleHeightPx = 22.0;
constexpr double kMarginBottomPx = 52.0;
constexpr double kLegendRowPx = 18.0;
constexpr double kLegendCharPx = 7.0;  // rough width of a 12 px sans-serif character
constexpr double kMaxPixel = 1e6;      // far outside the picture: clipped anyway, keeps numbers short

bool finite(double v) { return std::isfinite(v); }

/// Pixel coordinate with two decimals (enough for any screen).
std::string px(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", std::clamp(v, -kMaxPixel, kMaxPixel));
  return buf;
}

bool usable(double v, bool log) { return finite(v) && (!log || v > 0.0); }

double axisCoord(double v, bool log) { return log ? std::log10(v) : v; }

struct Range {
  double lo = 0.0, hi = 1.0;
};

/// Data range of one axis: the fixed ends where given, else the data with a
/// 5 % margin (of the log10 span on a log axis).
Range axisRange(const Axis& axis, const std::vector<double>& values, const char* name) {
  if (axis.log && ((axis.min && !(*axis.min > 0.0)) || (axis.max && !(*axis.max > 0.0)))) {
    throw std::invalid_argument(std::string("svg plot: ") + name + " axis is logarithmic, its min and max must be > 0");
  }
  if ((axis.min && !finite(*axis.min)) || (axis.max && !finite(*axis.max))) {
    throw std::invalid_argument(std::string("svg plot: ") + name + " axis min and max must be finite");
  }
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  for (double v : values) {
    lo = std::min(lo, axisCoord(v, axis.log));
    hi = std::max(hi, axisCoord(v, axis.log));
  }
  if (values.empty()) {
    lo = 0.0;
    hi = 1.0;
  } else if (hi - lo <= 1e-12 * std::max(1.0, std::abs(hi))) {
    const double pad = axis.log ? 0.3 : std::max(0.5, 0.1 * std::abs(hi));
    lo -= pad;
    hi += pad;
  }
  Range r{lo, hi};
  if (axis.min) r.lo = axisCoord(*axis.min, axis.log);
  if (axis.max) r.hi = axisCoord(*axis.max, axis.log);
  if (r.lo < r.hi) {
    // Margin on the automatic ends, relative to the span shown.
    const double margin = 0.05 * (r.hi - r.lo);
    if (!axis.min) r.lo -= margin;
    if (!axis.max) r.hi += margin;
  } else {
    if (axis.min && axis.max) {
      throw std::invalid_argument(std::string("svg plot: ") + name + " axis min must be below its max");
    }
    // One end fixed beyond all the data: show one unit (decade) from it.
    if (axis.min) {
      r.hi = r.lo + 1.0;
    } else {
      r.lo = r.hi - 1.0;
    }
  }
  return r;
}

std::string formatTick(double value, double step) {
  if (std::abs(value) < 1e-9 * std::abs(step)) value = 0.0;  // no "-0"
  int decimals = 0;
  if (step > 0.0 && step < 1.0) decimals = static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", std::clamp(decimals, 0, 9), value);
  return buf;
}

std::string formatG(double value) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%g", value);
  return buf;
}

/// Ticks of an axis: the given ones inside the range, else automatic ones.
std::vector<Tick> axisTicks(const Axis& axis, double lo, double hi, int target) {
  std::vector<Tick> ticks;
  const double tol = 1e-9 * (hi - lo);
  if (!axis.ticks.empty()) {
    for (const Tick& t : axis.ticks) {
      if (!usable(t.value, axis.log)) continue;
      const double c = axisCoord(t.value, axis.log);
      if (c >= lo - tol && c <= hi + tol) ticks.push_back(t);
    }
    return ticks;
  }
  if (!axis.log) {
    const std::vector<double> values = niceTicks(lo, hi, target);
    const double step = values.size() > 1 ? values[1] - values[0] : 1.0;
    for (double v : values) ticks.push_back({v, formatTick(v, step)});
    return ticks;
  }
  // Log axis: decades, plus 2x and 5x when fewer than three decades show.
  const int first = static_cast<int>(std::floor(lo));
  const int last = static_cast<int>(std::ceil(hi));
  const bool fine = last - first <= 3;
  for (int e = first; e <= last; ++e) {
    for (double m : {1.0, 2.0, 5.0}) {
      if (m != 1.0 && !fine) continue;
      const double v = m * std::pow(10.0, e);
      const double c = std::log10(v);
      if (c >= lo - tol && c <= hi + tol) ticks.push_back({v, formatG(v)});
    }
  }
  return ticks;
}

void appendSeriesMarkers(std::string& out, const Series& s, double x_px, double y_px) {
  const double r = s.marker_size_px;
  switch (s.marker) {
    case Marker::kNone:
      break;
    case Marker::kCircle:
      out += "<circle cx=\"" + px(x_px) + "\" cy=\"" + px(y_px) + "\" r=\"" + px(r) + "\"/>";
      break;
    case Marker::kSquare:
      out += "<rect x=\"" + px(x_px - r) + "\" y=\"" + px(y_px - r) + "\" width=\"" + px(2 * r) + "\" height=\"" +
             px(2 * r) + "\"/>";
      break;
    case Marker::kTriangle:
      out += "<polygon points=\"" + px(x_px) + "," + px(y_px - r) + " " + px(x_px - r) + "," + px(y_px + r) + " " +
             px(x_px + r) + "," + px(y_px + r) + "\"/>";
      break;
    case Marker::kCross:
      out += "<path d=\"M" + px(x_px - r) + "," + px(y_px - r) + "L" + px(x_px + r) + "," + px(y_px + r) + "M" +
             px(x_px - r) + "," + px(y_px + r) + "L" + px(x_px + r) + "," + px(y_px - r) + "\" fill=\"none\" stroke=\"" +
             xmlEscape(s.color) + "\" stroke-width=\"1.5\"/>";
      break;
  }
}

std::string lineStyle(const Series& s) {
  std::string style = "fill=\"none\" stroke=\"" + xmlEscape(s.color) + "\" stroke-width=\"" + px(s.line_width_px) +
                      "\" stroke-linejoin=\"round\" stroke-linecap=\"round\"";
  if (s.dashed) style += " stroke-dasharray=\"6 4\"";
  return style;
}

}  // namespace

double Layout::toPixelX(double x) const {
  const double lo = x_log ? std::log10(x_min) : x_min;
  const double hi = x_log ? std::log10(x_max) : x_max;
  return area.left + (axisCoord(x, x_log) - lo) / (hi - lo) * area.width;
}

double Layout::toPixelY(double y) const {
  const double lo = y_log ? std::log10(y_min) : y_min;
  const double hi = y_log ? std::log10(y_max) : y_max;
  return area.top + area.height - (axisCoord(y, y_log) - lo) / (hi - lo) * area.height;
}

Layout layoutOf(const Plot& plot) {
  if (plot.width_px < 160 || plot.height_px < 120 || plot.width_px > 20000 || plot.height_px > 20000) {
    throw std::invalid_argument("svg plot: width_px must be in [160, 20000] and height_px in [120, 20000]");
  }
  if (plot.equal_aspect && (plot.x.log || plot.y.log)) {
    throw std::invalid_argument("svg plot: equal_aspect needs linear axes");
  }
  std::vector<double> xs, ys;
  for (const Series& s : plot.series) {
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument("svg plot: series '" + s.label + "' has x and y of different lengths");
    }
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (usable(s.x[i], plot.x.log) && usable(s.y[i], plot.y.log)) {
        xs.push_back(s.x[i]);
        ys.push_back(s.y[i]);
      }
    }
  }
  Layout l;
  const double top = kMarginTopPx + (plot.title.empty() ? 0.0 : kTitleHeightPx);
  l.area = {kMarginLeftPx, top, plot.width_px - kMarginLeftPx - kMarginRightPx,
            plot.height_px - top - kMarginBottomPx};
  Range rx = axisRange(plot.x, xs, "x");
  Range ry = axisRange(plot.y, ys, "y");
  if (plot.equal_aspect) {
    // Same data units per pixel on both axes: widen the axis with room to spare.
    const double per_px = std::max((rx.hi - rx.lo) / l.area.width, (ry.hi - ry.lo) / l.area.height);
    const double cx = 0.5 * (rx.lo + rx.hi), cy = 0.5 * (ry.lo + ry.hi);
    rx = {cx - 0.5 * per_px * l.area.width, cx + 0.5 * per_px * l.area.width};
    ry = {cy - 0.5 * per_px * l.area.height, cy + 0.5 * per_px * l.area.height};
  }
  l.x_log = plot.x.log;
  l.y_log = plot.y.log;
  l.x_min = l.x_log ? std::pow(10.0, rx.lo) : rx.lo;
  l.x_max = l.x_log ? std::pow(10.0, rx.hi) : rx.hi;
  l.y_min = l.y_log ? std::pow(10.0, ry.lo) : ry.lo;
  l.y_max = l.y_log ? std::pow(10.0, ry.hi) : ry.hi;
  return l;
}

std::vector<double> niceTicks(double lo, double hi, int target) {
  if (!finite(lo) || !finite(hi) || !(hi > lo)) return finite(lo) ? std::vector<double>{lo} : std::vector<double>{};
  target = std::max(target, 2);
  const double raw = (hi - lo) / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  const double step = (norm < 1.5 ? 1.0 : norm < 3.0 ? 2.0 : norm < 7.0 ? 5.0 : 10.0) * mag;
  const double first = std::ceil(lo / step - 1e-9) * step;
  std::vector<double> ticks;
  for (int k = 0; k < 200; ++k) {
    const double v = first + k * step;
    if (v > hi + 1e-9 * step) break;
    ticks.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);
  }
  return ticks;
}

std::string xmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string renderSvg(const Plot& plot) {
  const Layout l = layoutOf(plot);
  const Rect& a = l.area;
  const double x_lo = axisCoord(l.x_min, l.x_log), x_hi = axisCoord(l.x_max, l.x_log);
  const double y_lo = axisCoord(l.y_min, l.y_log), y_hi = axisCoord(l.y_max, l.y_log);
  const std::vector<Tick> x_ticks = axisTicks(plot.x, x_lo, x_hi, 8);
  const std::vector<Tick> y_ticks = axisTicks(plot.y, y_lo, y_hi, 6);
  const std::string W = std::to_string(plot.width_px), H = std::to_string(plot.height_px);

  std::string out;
  out += "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  out += "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" + W + "\" height=\"" + H +
         "\" viewBox=\"0 0 " + W + " " + H + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  out += "<rect x=\"0\" y=\"0\" width=\"" + W + "\" height=\"" + H + "\" fill=\"white\"/>\n";
  const std::string area_attrs =
      "x=\"" + px(a.left) + "\" y=\"" + px(a.top) + "\" width=\"" + px(a.width) + "\" height=\"" + px(a.height) + "\"";
  out += "<defs><clipPath id=\"plot-clip\"><rect " + area_attrs + "/></clipPath></defs>\n";
  if (!plot.title.empty()) {
    out += "<text class=\"title\" x=\"" + px(0.5 * plot.width_px) + "\" y=\"" + px(kMarginTopPx + 8.0) +
           "\" text-anchor=\"middle\" font-size=\"14\" font-weight=\"bold\">" + xmlEscape(plot.title) + "</text>\n";
  }

  // Grid at the ticks, then the frame.
  out += "<g class=\"grid\" stroke=\"#e3e3e3\" stroke-width=\"1\">\n";
  for (const Tick& t : x_ticks) {
    const std::string x = px(l.toPixelX(t.value));
    out += "<line x1=\"" + x + "\" y1=\"" + px(a.top) + "\" x2=\"" + x + "\" y2=\"" + px(a.top + a.height) + "\"/>\n";
  }
  for (const Tick& t : y_ticks) {
    const std::string y = px(l.toPixelY(t.value));
    out += "<line x1=\"" + px(a.left) + "\" y1=\"" + y + "\" x2=\"" + px(a.left + a.width) + "\" y2=\"" + y + "\"/>\n";
  }
  out += "</g>\n";
  out += "<rect class=\"plot-area\" " + area_attrs + " fill=\"none\" stroke=\"#333333\" stroke-width=\"1\"/>\n";

  // Axes: tick marks, tick labels, axis labels.
  out += "<g class=\"axis x-axis\">\n";
  const double x_axis_y = a.top + a.height;
  for (const Tick& t : x_ticks) {
    const std::string x = px(l.toPixelX(t.value));
    out += "<line x1=\"" + x + "\" y1=\"" + px(x_axis_y) + "\" x2=\"" + x + "\" y2=\"" + px(x_axis_y + 5.0) +
           "\" stroke=\"#333333\"/>";
    out += "<text x=\"" + x + "\" y=\"" + px(x_axis_y + 18.0) + "\" text-anchor=\"middle\">" + xmlEscape(t.label) +
           "</text>\n";
  }
  if (!plot.x.label.empty()) {
    out += "<text class=\"axis-label\" x=\"" + px(a.left + 0.5 * a.width) + "\" y=\"" + px(x_axis_y + 40.0) +
           "\" text-anchor=\"middle\">" + xmlEscape(plot.x.label) + "</text>\n";
  }
  out += "</g>\n<g class=\"axis y-axis\">\n";
  for (const Tick& t : y_ticks) {
    const std::string y = px(l.toPixelY(t.value));
    out += "<line x1=\"" + px(a.left - 5.0) + "\" y1=\"" + y + "\" x2=\"" + px(a.left) + "\" y2=\"" + y +
           "\" stroke=\"#333333\"/>";
    out += "<text x=\"" + px(a.left - 8.0) + "\" y=\"" + px(l.toPixelY(t.value) + 4.0) + "\" text-anchor=\"end\">" +
           xmlEscape(t.label) + "</text>\n";
  }
  if (!plot.y.label.empty()) {
    const std::string lx = px(18.0), ly = px(a.top + 0.5 * a.height);
    out += "<text class=\"axis-label\" x=\"" + lx + "\" y=\"" + ly + "\" text-anchor=\"middle\" transform=\"rotate(-90 " +
           lx + " " + ly + ")\">" + xmlEscape(plot.y.label) + "</text>\n";
  }
  out += "</g>\n";

  // Series, clipped to the plot area.
  out += "<g clip-path=\"url(#plot-clip)\">\n";
  for (const Series& s : plot.series) {
    out += "<g class=\"series\" data-label=\"" + xmlEscape(s.label) + "\">\n";
    if (s.line_width_px > 0.0) {
      std::string points;
      std::size_t count = 0;
      const auto flush = [&] {
        if (count >= 2) out += "<polyline " + lineStyle(s) + " points=\"" + points + "\"/>\n";
        points.clear();
        count = 0;
      };
      for (std::size_t i = 0; i < s.x.size(); ++i) {
        if (!usable(s.x[i], l.x_log) || !usable(s.y[i], l.y_log)) {
          flush();
          continue;
        }
        if (count > 0) points += ' ';
        points += px(l.toPixelX(s.x[i])) + "," + px(l.toPixelY(s.y[i]));
        ++count;
      }
      flush();
    }
    if (s.marker != Marker::kNone) {
      out += "<g class=\"markers\" fill=\"" + xmlEscape(s.color) + "\" stroke=\"none\">";
      for (std::size_t i = 0; i < s.x.size(); ++i) {
        if (usable(s.x[i], l.x_log) && usable(s.y[i], l.y_log)) {
          appendSeriesMarkers(out, s, l.toPixelX(s.x[i]), l.toPixelY(s.y[i]));
        }
      }
      out += "</g>\n";
    }
    out += "</g>\n";
  }
  out += "</g>\n";

  // Legend in a corner of the plot area.
  std::vector<const Series*> entries;
  for (const Series& s : plot.series) {
    if (!s.label.empty()) entries.push_back(&s);
  }
  if (plot.legend != LegendPosition::kNone && !entries.empty()) {
    std::size_t longest = 0;
    for (const Series* s : entries) longest = std::max(longest, s->label.size());
    const double box_w = 40.0 + kLegendCharPx * static_cast<double>(longest);
    const double box_h = 8.0 + kLegendRowPx * static_cast<double>(entries.size());
    const auto corner = [&](LegendPosition pos) {
      const bool right = pos == LegendPosition::kTopRight || pos == LegendPosition::kBottomRight;
      const bool bottom = pos == LegendPosition::kBottomRight || pos == LegendPosition::kBottomLeft;
      return Rect{right ? a.left + a.width - 8.0 - box_w : a.left + 8.0,
                  bottom ? a.top + a.height - 8.0 - box_h : a.top + 8.0, box_w, box_h};
    };
    LegendPosition where = plot.legend;
    if (where == LegendPosition::kAuto) {
      std::size_t fewest = std::numeric_limits<std::size_t>::max();
      for (LegendPosition pos : {LegendPosition::kTopRight, LegendPosition::kTopLeft, LegendPosition::kBottomRight,
                                 LegendPosition::kBottomLeft}) {
        const Rect box = corner(pos);
        std::size_t covered = 0;
        for (const Series& s : plot.series) {
          for (std::size_t i = 0; i < s.x.size(); ++i) {
            if (usable(s.x[i], l.x_log) && usable(s.y[i], l.y_log) &&
                box.contains(l.toPixelX(s.x[i]), l.toPixelY(s.y[i]), 6.0)) {
              ++covered;
            }
          }
        }
        if (covered < fewest) {
          fewest = covered;
          where = pos;
        }
      }
    }
    const Rect box = corner(where);
    const double bx = box.left, by = box.top;
    out += "<g class=\"legend\">\n<rect x=\"" + px(bx) + "\" y=\"" + px(by) + "\" width=\"" + px(box_w) +
           "\" height=\"" + px(box_h) + "\" fill=\"white\" fill-opacity=\"0.85\" stroke=\"#999999\"/>\n";
    for (std::size_t i = 0; i < entries.size(); ++i) {
      const Series& s = *entries[i];
      const double cy = by + 4.0 + kLegendRowPx * (static_cast<double>(i) + 0.5);
      if (s.line_width_px > 0.0) {
        out += "<line x1=\"" + px(bx + 6.0) + "\" y1=\"" + px(cy) + "\" x2=\"" + px(bx + 30.0) + "\" y2=\"" + px(cy) +
               "\" " + lineStyle(s) + "/>";
      }
      if (s.marker != Marker::kNone) {
        out += "<g fill=\"" + xmlEscape(s.color) + "\" stroke=\"none\">";
        appendSeriesMarkers(out, s, bx + 18.0, cy);
        out += "</g>";
      }
      out += "<text x=\"" + px(bx + 36.0) + "\" y=\"" + px(cy + 4.0) + "\">" + xmlEscape(s.label) + "</text>\n";
    }
    out += "</g>\n";
  }
  out += "</svg>\n";
  return out;
}

void writeSvg(const std::filesystem::path& file, const Plot& plot) {
  const std::string svg = renderSvg(plot);
  std::ofstream out(file, std::ios::binary);
  out << svg;
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

}  // namespace rilo::svg
