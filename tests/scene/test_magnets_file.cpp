// The magnets file: the format of issue 2 is accepted exactly; every bad input is one InputError that names
// the file, line and key.

#include "magvine/scene/magnets_file.hpp"

#include <gtest/gtest.h>

#include "magvine/core/error.hpp"
#include "magvine/core/units.hpp"
#include "support/compare.hpp"

namespace magvine::scene {
namespace {

using magnetics::CylinderMagnet;
using magnetics::DipoleSource;
using magnetics::UniformSource;
using test::close;

// The example of issue 2, verbatim.
constexpr const char* kContract = R"(units: {length: mm}          # mm | cm | m; field values are always tesla, moments A·m²
magnets:
  - kind: cylinder
    diameter: 101.6
    length: 101.6
    polarisation: 1.48       # J in tesla (remanence of the magnet material)
    magnetisation: axial     # axial | diametric
    position: [0, 0, 0]      # centre
    axis: [0, 0, 1]          # cylinder axis = magnetisation direction for axial magnets
    # diametric magnets also take  direction: [1, 0, 0]  (magnetisation, perpendicular to axis)
  - kind: dipole
    position: [0, 0, 300]
    moment: [0, 0, 970.1]    # A·m²
  - kind: uniform
    field: [0, 0.01, 0]      # tesla
)";

TEST(MagnetsFile, AcceptsTheContractExample) {
  const auto model = parse_magnets(kContract, "contract.yaml");
  ASSERT_EQ(model.size(), 3u);
  const auto& cyl = std::get<CylinderMagnet>(model.sources[0]);
  EXPECT_NEAR(cyl.radius(), 0.0508, 1e-15);
  EXPECT_NEAR(cyl.length(), 0.1016, 1e-15);
  EXPECT_NEAR(cyl.dipole_moment().norm(), 970.1, 0.05);
  EXPECT_TRUE(close(Vec3(model.rest_poses[0].rotation.col(2)), Vec3(0, 0, 1), 1e-15));
  EXPECT_TRUE(close(model.rest_poses[1].position, Vec3(0, 0, 0.3), 1e-15));
  EXPECT_TRUE(close(std::get<DipoleSource>(model.sources[1]).moment, Vec3(0, 0, 970.1), 1e-15));
  EXPECT_TRUE(close(std::get<UniformSource>(model.sources[2]).b, Vec3(0, 0.01, 0), 1e-15));
}

TEST(MagnetsFile, UnitsScaleLengthsOnly) {
  const auto mm = parse_magnets("units: {length: mm}\nmagnets:\n  - {kind: cylinder, diameter: 20, length: 10, polarisation: 1.2, position: [1, 2, 3], axis: [0, 0, 1]}\n", "a");
  const auto cm = parse_magnets("units: {length: cm}\nmagnets:\n  - {kind: cylinder, diameter: 2, length: 1, polarisation: 1.2, position: [0.1, 0.2, 0.3], axis: [0, 0, 1]}\n", "b");
  const auto& a = std::get<CylinderMagnet>(mm.sources[0]);
  const auto& b = std::get<CylinderMagnet>(cm.sources[0]);
  EXPECT_NEAR(a.radius(), b.radius(), 1e-15);
  EXPECT_TRUE(close(mm.rest_poses[0].position, cm.rest_poses[0].position, 1e-15));
  EXPECT_NEAR(a.polarisation().z(), 1.2, 0);
}

TEST(MagnetsFile, DiametricDirectionAndDipoleFromVolume) {
  const auto model = parse_magnets(R"(units: {length: m}
magnets:
  - {kind: cylinder, diameter: 0.02, length: 0.02, remanence: 1.3, magnetisation: diametric,
     position: [0, 0, 0], axis: [0, 0, 2], direction: [0, 5, 0]}
  - {kind: dipole, position: [1, 0, 0], polarisation: 1.48, axis: [1, 0, 0], diameter: 0.1016, length: 0.1016}
  - {kind: cylinder, model: dipole, diameter: 0.1016, length: 0.1016, polarisation: 1.48, position: [0, 0, 0], axis: [0, 1, 0]}
)", "d");
  // Diametric magnetisation along world y.
  EXPECT_TRUE(close(Vec3(model.rest_poses[0].rotation * std::get<CylinderMagnet>(model.sources[0]).polarisation()),
                    Vec3(0, 1.3, 0), 1e-15));
  EXPECT_NEAR(std::get<DipoleSource>(model.sources[1]).moment.x(), 970.1, 0.05);
  EXPECT_NEAR((model.rest_poses[2].rotation * std::get<DipoleSource>(model.sources[2]).moment).y(), 970.1, 0.05);
}

std::string error_of(const std::string& text) {
  try {
    parse_magnets(text, "m.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MagnetsFile, BadInputNamesFileLineAndKey) {
  const std::string head = "units: {length: mm}\nmagnets:\n";
  const std::string cyl = "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1.4\n    position: [0, 0, 0]\n    axis: [0, 0, 1]\n";
  struct Case {
    std::string text;
    std::string expect;  // substring of the message
  };
  const std::vector<Case> cases = {
      {"", "m.yaml: empty file"},
      {"units: {length: mm}\n", "m.yaml:1: magnets: missing required key"},
      {"magnets: []\n", "units: missing required key"},
      {"units: {length: inch}\nmagnets: []\n", "m.yaml:1: units.length: must be mm, cm or m (got 'inch')"},
      {head + "  []\n", "magnets: is empty"},
      {head + cyl + "    diamter: 3\n", "m.yaml:9: magnets[0].diamter: unknown key (did you mean 'diameter'?"},
      {head + "  - kind: cylinder\n    diameter: -3\n", "m.yaml:4: magnets[0].diameter: must be in (0, 2000] mm (got -3)"},
      {head + "  - kind: cylinder\n    diameter: 0\n", "magnets[0].diameter: must be in (0, 2000] mm (got 0)"},
      {head + "  - kind: cylinder\n    diameter: .nan\n", "magnets[0].diameter: must be finite"},
      {head + "  - kind: cylinder\n    diameter: ten\n", "magnets[0].diameter: 'ten' is not a number"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    position: [0, 0, 0]\n", "magnets[0].polarisation: missing required key"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1480\n", "magnets[0].polarisation: must be in (0, 3] T (got 1480)"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1.4\n    position: [0, 0]\n", "m.yaml:7: magnets[0].position: must be a list of 3 numbers"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1.4\n    position: [0, .inf, 0]\n", "magnets[0].position[1]: must be finite"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1.4\n    position: [0, 0, 0]\n    axis: [0, 0, 0]\n", "magnets[0].axis: must not be the zero vector"},
      {head + cyl + "    direction: [1, 0, 0]\n", "magnets[0].direction: only diametric magnets take a direction"},
      {head + cyl + "    magnetisation: diametric\n", "magnets[0].direction: missing required key for a diametric magnet"},
      {head + cyl + "    magnetisation: diametric\n    direction: [0, 1, 1]\n", "magnets[0].direction: must be perpendicular to axis"},
      {head + cyl + "    magnetisation: radial\n", "magnets[0].magnetisation: must be axial or diametric"},
      {head + "  - kind: coil\n", "m.yaml:3: magnets[0].kind: must be cylinder, dipole or uniform (got 'coil')"},
      {head + "  - kind: dipole\n    position: [0, 0, 0]\n", "magnets[0].moment: missing required key"},
      {head + "  - kind: dipole\n    position: [0, 0, 0]\n    moment: [0, 0, 1]\n    volume: 3\n", "give either moment or polarisation"},
      {head + "  - kind: uniform\n    field: [0, 0]\n", "magnets[0].field: must be a list of 3 numbers"},
      {head + "  - kind: uniform\n    field: [0, 20, 0]\n", "m.yaml:4: magnets[0].field[1]: must be in [-10, 10] T (got 20)"},
      {head + "  - kind: cylinder\n    diameter: 10\n    length: 10\n    polarisation: 1.4\n    position: [0, 1e300, 0]\n",
       "m.yaml:7: magnets[0].position[1]: must be in [-10000, 10000] mm (got 1e+300)"},
      {"units: {length: mm\n", "m.yaml:2: YAML syntax error"},
      {"unit: {length: mm}\nmagnets: []\n", "m.yaml:1: unit: unknown key (did you mean 'units'?"},
  };
  for (const auto& c : cases) {
    const std::string msg = error_of(c.text);
    EXPECT_NE(msg.find(c.expect), std::string::npos) << "input:\n" << c.text << "\nmessage: " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "one line: " << msg;
  }
}

TEST(MagnetsFile, MissingFile) {
  EXPECT_THROW(load_magnets_file("/nonexistent/magnets.yaml"), InputError);
}

}  // namespace
}  // namespace magvine::scene
