#pragma once
// Text helpers shared by the report writers (report_markdown,
// tdoa_report_markdown): printf into a string, a Markdown table cell, a CSV
// field.
#include <string>

namespace rilo {

/// printf-style formatting into a std::string (checked like printf; at most 1023 characters).
[[gnu::format(printf, 1, 2)]] std::string strf(const char* format, ...);
/// Text safe inside a Markdown table cell: one line, '|' escaped.
std::string cellText(const std::string& s);
/// A quoted CSV field: '"' doubled, line breaks as spaces.
std::string csvField(const std::string& s);

}  // namespace rilo
