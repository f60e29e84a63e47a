#include "magvine/core/text.hpp"

#include <gtest/gtest.h>

#include <array>

namespace magvine {
namespace {

TEST(Text, EditDistance) {
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);
  EXPECT_EQ(edit_distance("", "abc"), 3u);
  EXPECT_EQ(edit_distance("same", "same"), 0u);
}

TEST(Text, ClosestMatchSuggestsTheIntendedKey) {
  const std::array<std::string_view, 4> keys{"diameter", "length", "polarisation", "position"};
  EXPECT_EQ(closest_match("diamter", keys), "diameter");
  EXPECT_EQ(closest_match("polarization", keys), "polarisation");
  EXPECT_EQ(closest_match("lenght", keys), "length");
}

TEST(Text, CsvQuotedKeepsCommasAndQuotesInOneField) {
  // RFC 4180: the field in double quotes, an inner quote doubled.
  EXPECT_EQ(csv_quoted(""), "\"\"");
  EXPECT_EQ(csv_quoted("blocked, 3 mm"), "\"blocked, 3 mm\"");
  EXPECT_EQ(csv_quoted("the \"lag\" did not settle"), "\"the \"\"lag\"\" did not settle\"");
}

}  // namespace
}  // namespace magvine
