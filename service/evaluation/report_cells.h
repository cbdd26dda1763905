#pragma once
// The report's table cells and labels (report_markdown.cpp builds the
// tables and figures from them): display names of the noise models,
// smoothers and rates, and mean/max cells with the paper's highlighting of
// the best within 5%. Not an interface: only the report's files include it.
#include <string>
#include <vector>

#include "evaluation/report.h"
#include "evaluation/svg_plot.h"

namespace rilo::report_detail {

std::string noiseLabel(const std::string& n);

std::string noiseColor(const std::string& n);

svg::Marker noiseMarker(const std::string& n);

std::string smootherLabel(const std::string& s);

std::string rateLabel(double hz);

/// Appends " text |" (a Markdown table cell). Written out piecewise: GCC 12
/// reports a false -Wrestrict for "literal" + std::string&& at -O3.
void appendCell(std::string& out, const std::string& text);

std::string joinList(const std::vector<std::string>& items);

/// The rates of Fig. 7 (the Fig. 7 list plus the Table I and II rates), ascending.
std::vector<double> figureRates(const ReportOptions& o);

// --- mean/max cells with the paper's highlighting ---------------------------

struct Cell {
  enum class Kind { kMissing, kNoTruth, kFail, kValue } kind = Kind::kMissing;
  double mean = 0.0, max = 0.0;
  bool bold_mean = false, bold_max = false;
  std::string fail_text = "Fail";
};

Cell apeCell(const ReportRun* run, double fail_mean_m, bool smoothed);

/// Mean over the recordings of a row: the average of the means and of the
/// maxima when every recording has a value.
Cell averageCell(const std::vector<Cell>& cells);

/// Bold within kBestTolerance of the best value of each column (mean and max separately).
void highlightColumns(std::vector<std::vector<Cell>>& rows, bool with_max);

std::string cellString(const Cell& c, bool with_max);

struct TableRow {
  std::vector<std::string> labels;
  std::vector<Cell> cells;  ///< one per recording (+ the average when more than one recording)
};

std::string renderCellTable(const std::vector<std::string>& label_headers, const std::vector<std::string>& columns,
                            std::vector<TableRow> rows, bool with_max);

std::vector<std::string> recordingColumns(const std::vector<ReportRecording>& recordings);

/// One row of mean/max cells over the recordings for (smoother, noise, rate).
std::vector<Cell> rowCells(const std::vector<ReportRecording>& recordings, const ReportResults& results,
                           const std::string& smoother, const std::string& noise, double rate, bool smoothed);

}  // namespace rilo::report_detail
