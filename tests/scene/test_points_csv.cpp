#include "magvine/scene/points_csv.hpp"

#include <gtest/gtest.h>

#include <sstream>

#include "magvine/core/error.hpp"

namespace magvine::scene {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_points_csv(text, "p.csv");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(PointsCsv, ParsesHeaderCommentsAndBlankLines) {
  const auto pts = parse_points_csv("# probe points\nx,y,z\n0.1, 0.2, 0.3\n\n-1e-3,0,2.5E-1\r\n", "p.csv");
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_EQ(pts[0], Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(pts[1], Vec3(-1e-3, 0, 0.25));
}

TEST(PointsCsv, BadInputNamesFileAndLine) {
  EXPECT_NE(error_of("").find("p.csv: empty file"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\n").find("p.csv: no points"), std::string::npos);
  EXPECT_NE(error_of("a,b,c\n1,2,3\n").find("p.csv:1: header: expected the header line 'x,y,z'"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\n1,2\n").find("p.csv:2: expected 3 columns x,y,z, got 2"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\n1,2,3\n1,abc,3\n").find("p.csv:3: column y: 'abc' is not a number"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\n1,2,nan\n").find("p.csv:2: column z: must be finite (got nan)"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\ninf,2,3\n").find("p.csv:2: column x: must be finite"), std::string::npos);
  EXPECT_NE(error_of("x,y,z\n1,2,\n").find("p.csv:2: column z: '' is not a number"), std::string::npos);
}

TEST(PointsCsv, OutputRoundTripsExactly) {
  const std::vector<Vec3> pts{Vec3(0.1, 1.0 / 3.0, -2e-300)};
  magnetics::FieldSample s;
  s.b = Vec3(1e-7, -0.123456789012345678, 3);
  s.g = Mat3::Identity() * (1.0 / 7.0);
  std::ostringstream out;
  write_field_csv(out, pts, std::vector<magnetics::FieldSample>{s});
  std::istringstream in(out.str());
  std::string header, row;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_EQ(header, "x,y,z,Bx,By,Bz,G11,G12,G13,G21,G22,G23,G31,G32,G33");
  std::vector<double> v;
  std::stringstream rs(row);
  std::string cell;
  while (std::getline(rs, cell, ',')) v.push_back(std::stod(cell));
  ASSERT_EQ(v.size(), 15u);
  EXPECT_EQ(v[1], 1.0 / 3.0);     // shortest round-trip form: exact
  EXPECT_EQ(v[4], -0.123456789012345678);
  EXPECT_EQ(v[6], 1.0 / 7.0);
}

}  // namespace
}  // namespace magvine::scene
