// Airway graph: building (ids, names, generations, children), queries (leaves, names, paths, lengths), JSON round
// trip in mm, and rejection of malformed files with the file and field named.

#include "magvine/anatomy/airway_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"

namespace magvine::anatomy {
namespace {

// A small Y with a second-level split on child 1:
//   0 ("0"): (0,0,0) → (0,0,−0.1) with a middle node; 1 ("0-0"), 2 ("0-1"), 3 ("0-1-0"), 4 ("0-1-1").
AirwayGraph sample_graph() {
  AirwayGraph g;
  const auto n0 = add_node(g, Vec3(0, 0, 0), 9e-3);
  const auto n1 = add_node(g, Vec3(0, 0, -0.05), 9e-3);
  const auto n2 = add_node(g, Vec3(0, 0, -0.1), 9e-3);
  const auto n3 = add_node(g, Vec3(0.03, 0, -0.14), 6e-3);
  const auto n4 = add_node(g, Vec3(-0.03, 0, -0.14), 6e-3);
  const auto n5 = add_node(g, Vec3(-0.03, 0.01, -0.16), 4e-3);
  const auto n6 = add_node(g, Vec3(-0.03, -0.01, -0.16), 4e-3);
  add_branch(g, -1, {n0, n1, n2});
  add_branch(g, 0, {n2, n3});
  add_branch(g, 0, {n2, n4});
  add_branch(g, 2, {n4, n5});
  add_branch(g, 2, {n4, n6});
  return g;
}

// Lengths are sums of exactly representable coordinates' norms: a few ulps of 0.1 m.
constexpr double kLengthTol = 1e-15;

TEST(AirwayGraph, BuildingAssignsIdsNamesGenerationsAndChildren) {
  const AirwayGraph g = sample_graph();
  ASSERT_EQ(g.branches.size(), 5u);
  const std::vector<std::string> names{"0", "0-0", "0-1", "0-1-0", "0-1-1"};
  const std::vector<int> parents{-1, 0, 0, 2, 2};
  const std::vector<int> generations{0, 1, 1, 2, 2};
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(g.branches[i].id, static_cast<int>(i));
    EXPECT_EQ(g.branches[i].name, names[i]);
    EXPECT_EQ(g.branches[i].parent, parents[i]);
    EXPECT_EQ(g.branches[i].generation, generations[i]);
  }
  EXPECT_EQ(g.branches[0].children, (std::vector<int>{1, 2}));
  EXPECT_EQ(g.branches[2].children, (std::vector<int>{3, 4}));
  EXPECT_NO_THROW(validate_graph(g, "sample"));
}

TEST(AirwayGraph, QueriesLeavesNamesPathsAndLengths) {
  const AirwayGraph g = sample_graph();
  EXPECT_EQ(leaves(g), (std::vector<int>{1, 3, 4}));
  EXPECT_EQ(find_branch(g, "0-1-1"), std::optional<int>(4));
  EXPECT_EQ(find_branch(g, "0-2"), std::nullopt);
  EXPECT_EQ(path_from_root(g, 4), (std::vector<int>{0, 2, 4}));
  EXPECT_EQ(path_from_root(g, 0), (std::vector<int>{0}));
  EXPECT_NEAR(branch_length(g, 0), 0.1, kLengthTol);
  EXPECT_NEAR(branch_length(g, 1), 0.05, kLengthTol);                 // 3-4-5 triangle: 30, 40 → 50 mm
  EXPECT_NEAR(branch_length(g, 3), std::hypot(0.01, 0.02), kLengthTol);
  EXPECT_NEAR(path_length(g, 4), 0.1 + 0.05 + std::hypot(0.01, 0.02), 4 * kLengthTol);
}

TEST(AirwayGraph, BuilderRejectsProgrammingErrors) {
  AirwayGraph g = sample_graph();
  EXPECT_THROW(add_branch(g, 7, {0, 1}), std::invalid_argument);  // no such parent
  EXPECT_THROW(add_branch(g, 1, {0, 1}), std::invalid_argument);  // does not start at the parent's end
  EXPECT_THROW(add_branch(g, -1, {0}), std::invalid_argument);    // one node
  EXPECT_THROW(add_branch(g, -1, {0, 99}), std::invalid_argument);
}

class AirwayGraphFile : public ::testing::Test {
 protected:
  void SetUp() override {
    m_dir = std::filesystem::temp_directory_path() /
            ("magvine_graph_test_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(m_dir);
  }
  void TearDown() override { std::filesystem::remove_all(m_dir); }
  std::filesystem::path m_dir;
};

TEST_F(AirwayGraphFile, JsonRoundTripIsExactToPrintingPrecisionAndInMillimetres) {
  const AirwayGraph g = sample_graph();
  const auto path = m_dir / "tree.graph.json";
  write_graph(path, g);
  // No temporary left behind, and the file states mm with mm values.
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(m_dir)) ++files;
  EXPECT_EQ(files, 1u);
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"units\": \"mm\""), std::string::npos);
  EXPECT_NE(text.find("-160"), std::string::npos);  // −0.16 m written as −160 mm

  const AirwayGraph back = read_graph(path);
  ASSERT_EQ(back.nodes.size(), g.nodes.size());
  ASSERT_EQ(back.branches.size(), g.branches.size());
  // mm ↔ m scaling by 1e-3 twice and 17-digit printing: within a few ulps.
  constexpr double kRoundTripTol = 1e-16;  // [m]
  for (std::size_t i = 0; i < g.nodes.size(); ++i) {
    EXPECT_LE((back.nodes[i].position - g.nodes[i].position).norm(), kRoundTripTol);
    EXPECT_NEAR(back.nodes[i].radius, g.nodes[i].radius, kRoundTripTol);
  }
  for (std::size_t i = 0; i < g.branches.size(); ++i) {
    EXPECT_EQ(back.branches[i].name, g.branches[i].name);
    EXPECT_EQ(back.branches[i].parent, g.branches[i].parent);
    EXPECT_EQ(back.branches[i].generation, g.branches[i].generation);
    EXPECT_EQ(back.branches[i].nodes, g.branches[i].nodes);
    EXPECT_EQ(back.branches[i].children, g.branches[i].children);
  }
}

TEST(AirwayGraph, AcceptsOtherLengthUnits) {
  const std::string text = R"({"units": "m", "nodes": [{"position": [0, 0, 0], "radius": 0.009},
      {"position": [0, 0, -0.1], "radius": 0.009}],
      "branches": [{"id": 0, "name": "0", "parent": -1, "generation": 0, "nodes": [0, 1], "children": []}]})";
  const AirwayGraph g = graph_from_json(text, "inline");
  EXPECT_NEAR(branch_length(g, 0), 0.1, kLengthTol);
  EXPECT_NEAR(g.nodes[0].radius, 0.009, kLengthTol);
}

// Each malformed document must fail with an InputError naming the source and the offending field.
struct Malformed {
  const char* what;
  std::string text;
  const char* field;
};

std::string with_branch(const std::string& branch, const std::string& extra_nodes = "") {
  return R"({"units": "mm", "nodes": [{"position": [0, 0, 0], "radius": 9}, {"position": [0, 0, -100], "radius": 9})" +
         extra_nodes + R"(], "branches": [)" + branch + "]}";
}

TEST(AirwayGraph, MalformedFilesNameTheFileAndField) {
  const std::string ok_root = R"({"id": 0, "name": "0", "parent": -1, "generation": 0, "nodes": [0, 1], "children": []})";
  const std::vector<Malformed> cases{
      {"not json", "{\"units\": ", "not valid JSON"},
      {"no units", R"({"nodes": [], "branches": []})", "units"},
      {"bad units", R"({"units": "inch", "nodes": [], "branches": []})", "units"},
      {"radius negative",
       R"({"units": "mm", "nodes": [{"position": [0, 0, 0], "radius": -1}, {"position": [0, 0, 1], "radius": 1}],
           "branches": [)" + ok_root + "]}",
       "nodes[0].radius"},
      {"position short", R"({"units": "mm", "nodes": [{"position": [0, 0], "radius": 1}], "branches": []})",
       "nodes[0].position"},
      {"no branches", R"({"units": "mm", "nodes": [], "branches": []})", "branches"},
      {"node index out of range",
       with_branch(R"({"id": 0, "name": "0", "parent": -1, "generation": 0, "nodes": [0, 5], "children": []})"),
       "branches[0].nodes"},
      {"wrong id", with_branch(R"({"id": 3, "name": "0", "parent": -1, "generation": 0, "nodes": [0, 1], "children": []})"),
       "branches[0].id"},
      {"missing parent", with_branch(R"({"id": 0, "name": "0", "generation": 0, "nodes": [0, 1], "children": []})"),
       "branches[0].parent"},
      {"wrong name", with_branch(R"({"id": 0, "name": "root", "parent": -1, "generation": 0, "nodes": [0, 1], "children": []})"),
       "branches[0].name"},
      {"child not starting at parent end",
       with_branch(ok_root.substr(0, ok_root.size() - 3) + R"([1]}, {"id": 1, "name": "0-0", "parent": 0, "generation": 1, "nodes": [0, 2], "children": []})",
                   R"(, {"position": [5, 0, -110], "radius": 6})"),
       "branches[1].nodes"},
      {"wrong generation",
       with_branch(ok_root.substr(0, ok_root.size() - 3) + R"([1]}, {"id": 1, "name": "0-0", "parent": 0, "generation": 4, "nodes": [1, 2], "children": []})",
                   R"(, {"position": [5, 0, -110], "radius": 6})"),
       "branches[1].generation"},
      {"children list missing the child",
       with_branch(ok_root + R"(, {"id": 1, "name": "0-0", "parent": 0, "generation": 1, "nodes": [1, 2], "children": []})",
                   R"(, {"position": [5, 0, -110], "radius": 6})"),
       "branches[0].children"},
      {"zero-length segment",
       with_branch(R"({"id": 0, "name": "0", "parent": -1, "generation": 0, "nodes": [0, 0], "children": []})"),
       "branches[0].nodes"},
  };
  for (const Malformed& c : cases) {
    try {
      graph_from_json(c.text, "bad.graph.json");
      ADD_FAILURE() << c.what << ": no error";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("bad.graph.json"), std::string::npos) << c.what << ": " << message;
      EXPECT_NE(message.find(c.field), std::string::npos) << c.what << ": " << message;
    }
  }
}

TEST_F(AirwayGraphFile, MissingFileIsAnInputErrorNamingIt) {
  const auto path = m_dir / "absent.graph.json";
  try {
    read_graph(path);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.graph.json"), std::string::npos);
  }
}

}  // namespace
}  // namespace magvine::anatomy
