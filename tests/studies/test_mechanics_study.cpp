// The skin MVR of thesis 4.7.1 (studies/mechanics_study.hpp): the discretised vine's snap against the thesis's
// two-stage model — both straight-ish before the crease, both creased and at the same angle after it.

#include <gtest/gtest.h>

#include <cstdio>

#include "magvine/studies/mechanics_study.hpp"

namespace magvine::studies {
namespace {

TEST(MechanicsStudy, SkinVineSnapsWhereTheTwoStageModelCreases) {
  // Torque setup, 6 kPa, EPM 65 mm up. At 160 mm both are in stage 1 (wrinkled, ~1.4°); at 132 mm both have creased
  // at the base and turned ~59° to the magnet. Tolerances: 0.5° before (the two models differ by the geometric
  // terms the two-stage model drops, ~0.1°), 2° after (stage 2 keeps the body straight beyond the crease; the
  // simulator's body also bends, measured 0.4°).
  const VineDeflectionPoint before = vine_deflection_point(true, 6e3, 0.160);
  const VineDeflectionPoint after = vine_deflection_point(true, 6e3, 0.132);
  std::printf("  160 mm: %.2f° (two-stage %.2f°, stage %d); 132 mm: %.2f° (two-stage %.2f°, stage %d)\n",
              before.angle_deg, before.two_stage_angle_deg, before.two_stage_stage, after.angle_deg,
              after.two_stage_angle_deg, after.two_stage_stage);
  ASSERT_TRUE(before.converged);
  ASSERT_TRUE(after.converged);
  EXPECT_FALSE(before.creased);
  EXPECT_EQ(before.two_stage_stage, 1);
  EXPECT_NEAR(before.angle_deg, before.two_stage_angle_deg, 0.5);
  EXPECT_LT(before.angle_deg, 5.0);
  EXPECT_TRUE(after.creased);
  EXPECT_EQ(after.two_stage_stage, 2);
  EXPECT_NEAR(after.angle_deg, after.two_stage_angle_deg, 2.0);
  EXPECT_GT(after.angle_deg, 45.0);
}

}  // namespace
}  // namespace magvine::studies
