#pragma once
/// Small text helpers for error messages.

#include <span>
#include <string>
#include <string_view>

namespace magvine {

/// Levenshtein edit distance.
std::size_t edit_distance(std::string_view a, std::string_view b);

/// The candidate closest to `word` by edit distance ("" when `candidates` is empty).
std::string closest_match(std::string_view word, std::span<const std::string_view> candidates);

}  // namespace magvine
