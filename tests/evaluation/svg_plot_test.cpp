#include "evaluation/svg_plot.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rilo::svg {
namespace {

// A tiny XML well-formedness check: one root element, balanced and properly
// nested tags, quoted attributes, only the five predefined entities (or
// numeric ones), no raw '<' or '&' in text or attribute values.
bool wellFormed(const std::string& xml, std::string* why) {
  std::vector<std::string> stack;
  std::size_t i = 0, roots = 0;
  const auto fail = [&](const std::string& what) {
    *why = what + " at offset " + std::to_string(i);
    return false;
  };
  const auto isNameChar = [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '-' || c == '_' || c == ':' || c == '.';
  };
  const auto entityOk = [&](std::size_t at) {
    const std::size_t semi = xml.find(';', at);
    if (semi == std::string::npos || semi - at > 10) return false;
    const std::string name = xml.substr(at + 1, semi - at - 1);
    return name == "amp" || name == "lt" || name == "gt" || name == "quot" || name == "apos" ||
           (name.size() > 1 && name[0] == '#');
  };
  if (xml.rfind("<?xml", 0) == 0) {
    i = xml.find("?>");
    if (i == std::string::npos) return fail("unterminated prolog");
    i += 2;
  }
  while (i < xml.size()) {
    const char c = xml[i];
    if (c == '&') {
      if (!entityOk(i)) return fail("bad entity in text");
      ++i;
      continue;
    }
    if (c != '<') {
      if (stack.empty() && !std::isspace(static_cast<unsigned char>(c))) return fail("text outside the root");
      ++i;
      continue;
    }
    if (xml.compare(i, 2, "</") == 0) {
      std::size_t j = i + 2;
      while (j < xml.size() && isNameChar(xml[j])) ++j;
      const std::string name = xml.substr(i + 2, j - i - 2);
      if (j >= xml.size() || xml[j] != '>') return fail("bad closing tag");
      if (stack.empty() || stack.back() != name) return fail("closing </" + name + "> does not match");
      stack.pop_back();
      i = j + 1;
      continue;
    }
    std::size_t j = i + 1;
    while (j < xml.size() && isNameChar(xml[j])) ++j;
    const std::string name = xml.substr(i + 1, j - i - 1);
    if (name.empty()) return fail("empty tag name");
    if (stack.empty()) ++roots;
    bool self_closing = false;
    for (;;) {
      while (j < xml.size() && std::isspace(static_cast<unsigned char>(xml[j]))) ++j;
      if (j >= xml.size()) return fail("unterminated tag <" + name + ">");
      if (xml.compare(j, 2, "/>") == 0) {
        self_closing = true;
        j += 2;
        break;
      }
      if (xml[j] == '>') {
        ++j;
        break;
      }
      const std::size_t a0 = j;
      while (j < xml.size() && isNameChar(xml[j])) ++j;
      if (j == a0) return fail("bad attribute in <" + name + ">");
      if (j + 1 >= xml.size() || xml[j] != '=' || xml[j + 1] != '"') return fail("unquoted attribute in <" + name + ">");
      const std::size_t end = xml.find('"', j + 2);
      if (end == std::string::npos) return fail("unterminated attribute value");
      for (std::size_t k = j + 2; k < end; ++k) {
        if (xml[k] == '<') return fail("raw < in an attribute");
        if (xml[k] == '&' && !entityOk(k)) return fail("bad entity in an attribute");
      }
      j = end + 1;
    }
    if (!self_closing) stack.push_back(name);
    i = j;
  }
  if (!stack.empty()) return fail("unclosed <" + stack.back() + ">");
  if (roots != 1) return fail("expected one root element, got " + std::to_string(roots));
  return true;
}

double attr(const std::string& element, const std::string& name) {
  const std::regex re("\\s" + name + "=\"([-0-9.eE+]+)\"");
  std::smatch m;
  if (!std::regex_search(element, m, re)) throw std::runtime_error("no attribute " + name + " in " + element);
  return std::stod(m[1]);
}

Rect plotArea(const std::string& svg) {
  std::smatch m;
  if (!std::regex_search(svg, m, std::regex("<rect class=\"plot-area\"[^>]*>"))) throw std::runtime_error("no plot-area");
  const std::string e = m[0];
  return {attr(e, "x"), attr(e, "y"), attr(e, "width"), attr(e, "height")};
}

/// Every vertex of every polyline and every circle centre inside the series groups.
std::vector<std::pair<double, double>> seriesPoints(const std::string& svg) {
  std::vector<std::pair<double, double>> pts;
  const std::size_t begin = svg.find("<g class=\"series\"");
  const std::size_t end = svg.find("<g class=\"legend\"");
  const std::string body = svg.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
  const std::regex poly("<polyline[^>]* points=\"([^\"]*)\"");
  for (auto it = std::sregex_iterator(body.begin(), body.end(), poly); it != std::sregex_iterator(); ++it) {
    std::istringstream in((*it)[1].str());
    std::string pair;
    while (in >> pair) {
      const std::size_t comma = pair.find(',');
      pts.emplace_back(std::stod(pair.substr(0, comma)), std::stod(pair.substr(comma + 1)));
    }
  }
  const std::regex circle("<circle cx=\"([-0-9.]+)\" cy=\"([-0-9.]+)\"");
  for (auto it = std::sregex_iterator(body.begin(), body.end(), circle); it != std::sregex_iterator(); ++it) {
    pts.emplace_back(std::stod((*it)[1].str()), std::stod((*it)[2].str()));
  }
  return pts;
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + 1)) ++n;
  return n;
}

Plot samplePlot() {
  Plot p;
  p.title = "Errors <3D> & \"friends\"";
  p.x.label = "Time (s)";
  p.y.label = "Error (m)";
  Series a;
  a.label = "3D";
  a.x = {0.0, 1.0, 2.0, 3.0, 4.0};
  a.y = {0.5, 1.5, 0.7, 2.5, 1.0};
  Series b;
  b.label = "Horizontal 'xy'";
  b.color = "#ff7f0e";
  b.marker = Marker::kCircle;
  b.x = {0.0, 1.0, 2.0, 3.0, 4.0};
  b.y = {0.2, 0.4, 0.3, 0.9, 0.6};
  Series c;
  c.label = "Anchors";
  c.line_width_px = 0.0;
  c.marker = Marker::kSquare;
  c.x = {-1.0, 5.0};
  c.y = {3.0, -0.5};
  Series d;
  d.label = "Markers";
  d.marker = Marker::kTriangle;
  d.x = {1.5, 2.5};
  d.y = {2.0, 2.2};
  Series e;
  e.marker = Marker::kCross;  // unlabelled: not in the legend
  e.dashed = true;
  e.x = {0.5, 3.5};
  e.y = {0.1, 0.1};
  p.series = {a, b, c, d, e};
  return p;
}

TEST(SvgPlot, OutputIsWellFormedXmlWithEscapedText) {
  const std::string svg = renderSvg(samplePlot());
  std::string why;
  EXPECT_TRUE(wellFormed(svg, &why)) << why;
  EXPECT_NE(svg.find("<svg xmlns=\"http://www.w3.org/2000/svg\""), std::string::npos);
  EXPECT_NE(svg.find("Errors &lt;3D&gt; &amp; &quot;friends&quot;"), std::string::npos);
  EXPECT_EQ(svg.find("<3D>"), std::string::npos);
  EXPECT_NE(svg.find("Time (s)"), std::string::npos);
  EXPECT_NE(svg.find("Error (m)"), std::string::npos);
}

TEST(SvgPlot, WellFormednessCheckRejectsBrokenDocuments) {
  std::string why;
  EXPECT_FALSE(wellFormed("<svg><g></svg>", &why));
  EXPECT_FALSE(wellFormed("<svg><g></g>", &why));
  EXPECT_FALSE(wellFormed("<svg a=1></svg>", &why));
  EXPECT_FALSE(wellFormed("<svg>a & b</svg>", &why));
  EXPECT_FALSE(wellFormed("<svg/><svg/>", &why));
  EXPECT_TRUE(wellFormed("<svg a=\"1\"><g/>x &amp; y</svg>", &why)) << why;
}

TEST(SvgPlot, PointsAreMappedIntoThePlotArea) {
  const Plot plot = samplePlot();
  const std::string svg = renderSvg(plot);
  const Rect area = plotArea(svg);
  EXPECT_GT(area.width, 100.0);
  EXPECT_GT(area.height, 100.0);
  EXPECT_LE(area.left + area.width, plot.width_px);
  EXPECT_LE(area.top + area.height, plot.height_px);
  const auto pts = seriesPoints(svg);
  // 5 + 5 vertices of the two lines, 2 + 2 of the dashed ones, 5 circles.
  ASSERT_EQ(pts.size(), 19u);
  for (const auto& [x, y] : pts) EXPECT_TRUE(area.contains(x, y, 0.01)) << x << "," << y;

  // The layout the renderer used: extreme data points land inside, ordered.
  const Layout l = layoutOf(plot);
  EXPECT_NEAR(l.area.left, area.left, 0.01);
  EXPECT_NEAR(l.area.top, area.top, 0.01);
  EXPECT_LT(l.toPixelX(-1.0), l.toPixelX(5.0));
  EXPECT_GT(l.toPixelY(-0.5), l.toPixelY(3.0));  // y grows upwards in data, downwards in pixels
  EXPECT_TRUE(area.contains(l.toPixelX(-1.0), l.toPixelY(-0.5)));
  EXPECT_TRUE(area.contains(l.toPixelX(5.0), l.toPixelY(3.0)));
}

TEST(SvgPlot, FixedRangeMapsItsEndsToTheCorners) {
  Plot p;
  p.x.min = 0.0;
  p.x.max = 10.0;
  p.y.min = -2.0;
  p.y.max = 2.0;
  p.series.push_back({"line", {0.0, 10.0}, {-2.0, 2.0}});
  const Layout l = layoutOf(p);
  EXPECT_NEAR(l.toPixelX(0.0), l.area.left, 1e-9);
  EXPECT_NEAR(l.toPixelX(10.0), l.area.left + l.area.width, 1e-9);
  EXPECT_NEAR(l.toPixelY(-2.0), l.area.top + l.area.height, 1e-9);
  EXPECT_NEAR(l.toPixelY(2.0), l.area.top, 1e-9);
  EXPECT_NEAR(l.toPixelX(5.0), l.area.left + 0.5 * l.area.width, 1e-9);
}

TEST(SvgPlot, LegendListsTheLabelledSeries) {
  const std::string svg = renderSvg(samplePlot());
  const std::size_t legend = svg.find("<g class=\"legend\">");
  ASSERT_NE(legend, std::string::npos);
  const std::string box = svg.substr(legend, svg.find("</g>\n</svg>") - legend);
  for (const char* label : {">3D<", ">Horizontal &apos;xy&apos;<", ">Anchors<", ">Markers<"}) {
    EXPECT_NE(box.find(label), std::string::npos) << label;
  }
  EXPECT_EQ(count(box, "<text"), 4u);  // the unlabelled series has no entry

  Plot none = samplePlot();
  none.legend = LegendPosition::kNone;
  EXPECT_EQ(renderSvg(none).find("class=\"legend\""), std::string::npos);
}

TEST(SvgPlot, AutomaticLegendAvoidsTheData) {
  Plot p;
  p.x.min = 0.0;
  p.x.max = 10.0;
  p.y.min = 0.0;
  p.y.max = 10.0;
  Series s{"data in the top right", {}, {}};
  s.line_width_px = 0.0;
  s.marker = Marker::kCircle;
  for (double x = 6.0; x <= 10.0; x += 0.25) {
    for (double y = 6.0; y <= 10.0; y += 0.25) {
      s.x.push_back(x);
      s.y.push_back(y);
    }
  }
  p.series.push_back(s);
  const std::string svg = renderSvg(p);
  std::smatch m;
  const std::string from = svg.substr(svg.find("<g class=\"legend\">"));
  ASSERT_TRUE(std::regex_search(from, m, std::regex("<rect[^>]*>")));
  const Layout l = layoutOf(p);
  EXPECT_LT(attr(m[0], "x"), l.area.left + 0.5 * l.area.width);  // moved to a left corner
}

TEST(SvgPlot, NonFiniteValuesBreakTheLine) {
  Plot p;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  p.series.push_back({"gappy", {0.0, 1.0, nan, 3.0, 4.0, 5.0}, {0.0, 1.0, 2.0, 3.0, 4.0, 5.0}});
  const std::string svg = renderSvg(p);
  EXPECT_EQ(count(svg, "<polyline"), 2u);
  EXPECT_EQ(seriesPoints(svg).size(), 5u);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
}

TEST(SvgPlot, LogAxisUsesGivenTicksAndDropsNonPositiveValues) {
  Plot p;
  p.x.log = true;
  for (double r : {1.0, 2.0, 4.0, 8.0, 20.0, 40.0}) p.x.ticks.push_back({r, std::to_string(static_cast<int>(r)) + " Hz"});
  p.series.push_back({"ape", {0.0, 1.0, 2.0, 4.0, 8.0, 20.0, 40.0}, {9.0, 1.0, 0.8, 0.7, 0.6, 0.5, 0.4}});
  const std::string svg = renderSvg(p);
  std::string why;
  EXPECT_TRUE(wellFormed(svg, &why)) << why;
  for (const char* t : {">1 Hz<", ">2 Hz<", ">4 Hz<", ">8 Hz<", ">20 Hz<", ">40 Hz<"}) {
    EXPECT_NE(svg.find(t), std::string::npos) << t;
  }
  EXPECT_EQ(seriesPoints(svg).size(), 6u);  // x = 0 cannot be shown on a log axis
  const Layout l = layoutOf(p);
  // Equal ratios are equal distances.
  EXPECT_NEAR(l.toPixelX(2.0) - l.toPixelX(1.0), l.toPixelX(40.0) - l.toPixelX(20.0), 1e-9);
  EXPECT_GT(l.y_max, 0.99);  // the y range ignores the dropped point (y = 9)
  EXPECT_LT(l.y_max, 2.0);
}

TEST(SvgPlot, EqualAspectGivesOneScaleOnBothAxes) {
  Plot p;
  p.equal_aspect = true;
  p.series.push_back({"walk", {0.0, 20.0, 20.0, 0.0}, {0.0, 0.0, 2.0, 2.0}});
  const Layout l = layoutOf(p);
  const double px_per_m_x = (l.toPixelX(1.0) - l.toPixelX(0.0));
  const double px_per_m_y = (l.toPixelY(0.0) - l.toPixelY(1.0));
  EXPECT_NEAR(px_per_m_x, px_per_m_y, 1e-9);
  for (double x : {0.0, 20.0}) {
    for (double y : {0.0, 2.0}) EXPECT_TRUE(l.area.contains(l.toPixelX(x), l.toPixelY(y)));
  }
}

TEST(SvgPlot, BadInputThrowsNamingTheProblem) {
  Plot mismatch;
  mismatch.series.push_back({"bad", {0.0, 1.0}, {0.0}});
  try {
    renderSvg(mismatch);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'bad'"), std::string::npos);
  }
  Plot log;
  log.x.log = true;
  log.x.min = 0.0;
  EXPECT_THROW(layoutOf(log), std::invalid_argument);
  Plot inverted;
  inverted.y.min = 2.0;
  inverted.y.max = 1.0;
  EXPECT_THROW(layoutOf(inverted), std::invalid_argument);
  Plot tiny;
  tiny.width_px = 10;
  EXPECT_THROW(layoutOf(tiny), std::invalid_argument);
  Plot aspect_log;
  aspect_log.equal_aspect = true;
  aspect_log.y.log = true;
  EXPECT_THROW(layoutOf(aspect_log), std::invalid_argument);
}

TEST(SvgPlot, EmptyPlotStillRenders) {
  Plot p;
  p.title = "nothing";
  const std::string svg = renderSvg(p);
  std::string why;
  EXPECT_TRUE(wellFormed(svg, &why)) << why;
  EXPECT_EQ(svg.find("class=\"legend\""), std::string::npos);
}

TEST(SvgPlot, NiceTicksUseOneTwoFiveSteps) {
  EXPECT_EQ(niceTicks(0.0, 10.0, 5), (std::vector<double>{0.0, 2.0, 4.0, 6.0, 8.0, 10.0}));
  const std::vector<double> unit = niceTicks(0.0, 1.0, 5);
  ASSERT_EQ(unit.size(), 6u);
  for (std::size_t k = 0; k < unit.size(); ++k) EXPECT_NEAR(unit[k], 0.2 * static_cast<double>(k), 1e-12);
  const std::vector<double> t = niceTicks(-3.7, 12.2, 6);
  ASSERT_GE(t.size(), 4u);
  EXPECT_GE(t.front(), -3.7);
  EXPECT_LE(t.back(), 12.2);
  const double step = t[1] - t[0];
  EXPECT_NEAR(step, 2.0, 1e-12);  // 15.9 / 6 = 2.65 -> 2
  for (std::size_t k = 1; k < t.size(); ++k) EXPECT_NEAR(t[k] - t[k - 1], step, 1e-9);
  EXPECT_NEAR(niceTicks(0.0, 7.0, 7)[1], 1.0, 1e-12);
  EXPECT_TRUE(niceTicks(1.0, 1.0, 5).size() == 1);
}

TEST(SvgPlot, WriteSvgWritesTheRenderedDocument) {
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("rilo_svg_plot_test_" + std::to_string(::getpid()) + ".svg");
  writeSvg(file, samplePlot());
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), renderSvg(samplePlot()));
  std::filesystem::remove(file);
  EXPECT_THROW(writeSvg("/nonexistent-dir/x.svg", samplePlot()), std::runtime_error);
}

}  // namespace
}  // namespace rilo::svg
