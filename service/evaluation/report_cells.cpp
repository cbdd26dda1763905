#include "evaluation/report_cells.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "evaluation/report_text.h"

namespace rilo::report_detail {

namespace {

constexpr double kBestTolerance = 0.05;  // the paper highlights the best "with 5% tolerance"

}  // namespace

std::string noiseLabel(const std::string& n) {
  if (n == "asymmetric") return "Asymmetric (proposed)";
  if (n == "asymmetric-half-cauchy") return "Asymmetric half-Cauchy";
  if (n == "gaussian") return "Gaussian";
  if (n == "huber") return "Huber";
  if (n == "cauchy") return "Cauchy";
  return n;
}

std::string noiseColor(const std::string& n) {
  if (n == "asymmetric") return "#1f77b4";
  if (n == "gaussian") return "#2ca02c";
  if (n == "huber") return "#ff7f0e";
  if (n == "cauchy") return "#9467bd";
  return "#8c564b";
}

svg::Marker noiseMarker(const std::string& n) {
  if (n == "asymmetric") return svg::Marker::kCircle;
  if (n == "gaussian") return svg::Marker::kSquare;
  if (n == "huber") return svg::Marker::kTriangle;
  return svg::Marker::kCross;
}

std::string smootherLabel(const std::string& s) {
  if (s == "d-isam2") return "D-iSAM2";
  if (s == "isam2") return "iSAM2";
  if (s == "dogleg") return "RISE (dog-leg)";
  return s;
}

std::string rateLabel(double hz) { return strf("%g Hz", hz); }

/// Appends " text |" (a Markdown table cell). Written out piecewise: GCC 12
/// reports a false -Wrestrict for "literal" + std::string&& at -O3.
void appendCell(std::string& out, const std::string& text) {
  out += ' ';
  out += text;
  out += " |";
}

std::string joinList(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

/// The rates of Fig. 7 (the Fig. 7 list plus the Table I and II rates), ascending.
std::vector<double> figureRates(const ReportOptions& o) {
  std::vector<double> rates = o.rates_hz;
  for (double r : {o.low_rate_hz, o.full_rate_hz}) {
    if (std::none_of(rates.begin(), rates.end(), [r](double x) { return std::abs(x - r) <= 1e-9 * r; })) {
      rates.push_back(r);
    }
  }
  std::sort(rates.begin(), rates.end());
  return rates;
}

// ---------------------------------------------------------------------------
// mean/max cells with the paper's highlighting

Cell apeCell(const ReportRun* run, double fail_mean_m, bool smoothed) {
  Cell c;
  if (run == nullptr) return c;
  if (run->threw) {
    c.kind = Cell::Kind::kFail;
    return c;
  }
  if (!run->has_truth) {
    c.kind = Cell::Kind::kNoTruth;
    return c;
  }
  const ErrorStats& e = smoothed ? run->ape_smoothed.ape_3d : run->ape_online.ape_3d;
  if (run->failed(fail_mean_m) || e.count == 0 || !(e.mean <= fail_mean_m)) {
    c.kind = Cell::Kind::kFail;
    return c;
  }
  c.kind = Cell::Kind::kValue;
  c.mean = e.mean;
  c.max = e.max;
  return c;
}

/// Mean over the recordings of a row: the average of the means and of the
/// maxima when every recording has a value.
Cell averageCell(const std::vector<Cell>& cells) {
  Cell avg;
  if (cells.empty()) return avg;
  std::size_t fails = 0, values = 0;
  for (const Cell& c : cells) {
    if (c.kind == Cell::Kind::kFail) ++fails;
    if (c.kind == Cell::Kind::kValue) {
      avg.mean += c.mean;
      avg.max += c.max;
      ++values;
    }
  }
  if (fails > 0) {
    avg.kind = Cell::Kind::kFail;
    avg.fail_text = strf("Fail (%zu of %zu)", fails, cells.size());
  } else if (values == cells.size()) {
    avg.kind = Cell::Kind::kValue;
    avg.mean /= static_cast<double>(values);
    avg.max /= static_cast<double>(values);
  } else {
    avg.kind = values == 0 && std::any_of(cells.begin(), cells.end(),
                                          [](const Cell& c) { return c.kind == Cell::Kind::kNoTruth; })
                   ? Cell::Kind::kNoTruth
                   : Cell::Kind::kMissing;
  }
  return avg;
}

/// Bold within kBestTolerance of the best value of each column (mean and max separately).
void highlightColumns(std::vector<std::vector<Cell>>& rows, bool with_max) {
  if (rows.size() < 2) return;
  const std::size_t columns = rows.front().size();
  for (std::size_t c = 0; c < columns; ++c) {
    double best_mean = std::numeric_limits<double>::infinity(), best_max = best_mean;
    for (const auto& row : rows) {
      if (row[c].kind != Cell::Kind::kValue) continue;
      best_mean = std::min(best_mean, row[c].mean);
      best_max = std::min(best_max, row[c].max);
    }
    for (auto& row : rows) {
      if (row[c].kind != Cell::Kind::kValue) continue;
      row[c].bold_mean = row[c].mean <= best_mean * (1.0 + kBestTolerance) + 1e-12;
      row[c].bold_max = with_max && row[c].max <= best_max * (1.0 + kBestTolerance) + 1e-12;
    }
  }
}

std::string cellString(const Cell& c, bool with_max) {
  switch (c.kind) {
    case Cell::Kind::kMissing: return "–";
    case Cell::Kind::kNoTruth: return "n/a";
    case Cell::Kind::kFail: return c.fail_text;
    case Cell::Kind::kValue: break;
  }
  std::string mean = strf("%.2f", c.mean);
  if (c.bold_mean) mean = "**" + mean + "**";
  if (!with_max) return mean;
  std::string max = strf("%.2f", c.max);
  if (c.bold_max) max = "**" + max + "**";
  return mean + "/" + max;
}

std::string renderCellTable(const std::vector<std::string>& label_headers, const std::vector<std::string>& columns,
                            std::vector<TableRow> rows, bool with_max) {
  std::vector<std::vector<Cell>> cells;
  for (const TableRow& r : rows) cells.push_back(r.cells);
  highlightColumns(cells, with_max);
  std::string out = "|";
  for (const std::string& h : label_headers) appendCell(out, h);
  for (const std::string& c : columns) appendCell(out, cellText(c));
  out += "\n|";
  for (std::size_t i = 0; i < label_headers.size(); ++i) out += "---|";
  for (std::size_t i = 0; i < columns.size(); ++i) out += "---:|";
  out += "\n";
  for (std::size_t r = 0; r < rows.size(); ++r) {
    out += "|";
    for (const std::string& l : rows[r].labels) appendCell(out, cellText(l));
    for (const Cell& c : cells[r]) appendCell(out, cellString(c, with_max));
    out += "\n";
  }
  return out;
}

std::vector<std::string> recordingColumns(const std::vector<ReportRecording>& recordings) {
  std::vector<std::string> cols;
  for (const ReportRecording& r : recordings) cols.push_back(r.label);
  if (recordings.size() > 1) cols.push_back("Mean");
  return cols;
}

/// One row of mean/max cells over the recordings for (smoother, noise, rate).
std::vector<Cell> rowCells(const std::vector<ReportRecording>& recordings, const ReportResults& results,
                           const std::string& smoother, const std::string& noise, double rate, bool smoothed) {
  std::vector<Cell> cells;
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    cells.push_back(apeCell(results.find(i, smoother, noise, rate), results.options.fail_mean_m, smoothed));
  }
  if (recordings.size() > 1) cells.push_back(averageCell(cells));
  return cells;
}

}  // namespace rilo::report_detail
