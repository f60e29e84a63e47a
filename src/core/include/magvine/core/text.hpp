#pragma once
/// Small text helpers for error messages, event details and CSV rows.

#include <cstdio>
#include <span>
#include <string>
#include <string_view>

namespace magvine {

/// Levenshtein edit distance.
std::size_t edit_distance(std::string_view a, std::string_view b);

/// The candidate closest to `word` by edit distance ("" when `candidates` is empty).
std::string closest_match(std::string_view word, std::span<const std::string_view> candidates);

/// Appends the shortest round-trip decimal form of v.
void append_number(std::string& s, double v);
/// Appends `values` comma-separated (shortest round-trip form) and a newline.
void append_csv_row(std::string& s, std::span<const double> values);
/// `text` as one CSV field: in double quotes, each quote doubled (RFC 4180), so commas and quotes stay inside it.
std::string csv_quoted(std::string_view text);

/// printf into a string, any length (numbers with units in events and messages: printf_string("%.1f mm", x)).
template <typename... Args>
std::string printf_string(const char* pattern, Args... args) {
  const int n = std::snprintf(nullptr, 0, pattern, args...);
  if (n <= 0) return {};
  std::string text(static_cast<std::size_t>(n), '\0');
  std::snprintf(text.data(), text.size() + 1, pattern, args...);
  return text;
}

}  // namespace magvine
