// Ridge files are validated when read (issue 14, defect 5): a NaN or a non-positive size in any
// dataset is an InputError naming the dataset, row and column, never a crash at the first step.
#include <gtest/gtest.h>

#include "common/error.h"
#include "io/ridge_file.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

namespace fs = std::filesystem;
using namespace hs;

namespace {

rigid::RidgeResult two_blocks() {
  rigid::RidgeResult r;
  r.def.name = "guards";
  rigid::RidgeBlock b;
  b.half_extents = Vec3(0.5, 0.5, 0.1);
  b.position = Vec3(0, 0, -1);
  r.blocks.push_back(b);
  b.position = Vec3(1.0, 0, -1);
  r.blocks.push_back(b);
  rigid::RidgeJoint j;
  j.a = 0;
  j.b = 1;
  j.anchor = Vec3(0.5, 0, -1);
  j.normal = Vec3::UnitX();
  j.area = 0.1;
  r.joints.push_back(j);
  r.profile.x = {0.0};
  r.profile.keel_target = {1.0};
  r.profile.keel_depth = {1.0};
  r.profile.sail_target = {0.0};
  r.profile.sail_height = {0.0};
  return r;
}

std::string load_error(const rigid::RidgeResult& r) {
  const fs::path p = fs::temp_directory_path() / ("hs_ridge_guard_" + std::to_string(::getpid()) + ".h5");
  io::save_ridge(p.string(), r);
  std::string msg;
  try {
    io::load_ridge(p.string());
  } catch (const InputError& e) {
    msg = e.what();
  }
  fs::remove(p);
  return msg;
}

}  // namespace

TEST(RidgeFileGuards, AValidFileLoads) { EXPECT_EQ(load_error(two_blocks()), ""); }

TEST(RidgeFileGuards, NaNPositionIsRefusedWithDatasetAndIndex) {
  auto r = two_blocks();
  r.blocks[1].position.y() = std::numeric_limits<double>::quiet_NaN();
  const std::string m = load_error(r);
  EXPECT_NE(m.find("/ridge/blocks/position row 1 column 1"), std::string::npos) << m;
  EXPECT_NE(m.find("finite"), std::string::npos) << m;
}

TEST(RidgeFileGuards, NonPositiveOrInfiniteSizesAreRefused) {
  auto r = two_blocks();
  r.blocks[0].half_extents.z() = -0.1;
  std::string m = load_error(r);
  EXPECT_NE(m.find("/ridge/blocks/half_extents row 0 column 2"), std::string::npos) << m;
  EXPECT_NE(m.find("> 0"), std::string::npos) << m;
  r = two_blocks();
  r.joints[0].area = std::numeric_limits<double>::infinity();
  m = load_error(r);
  EXPECT_NE(m.find("/ridge/joints/area row 0"), std::string::npos) << m;
  r = two_blocks();
  r.blocks[1].orientation = Quat(0, 0, 0, 0);
  m = load_error(r);
  EXPECT_NE(m.find("/ridge/blocks/orientation row 1"), std::string::npos) << m;
}
