// Keyframe interpolation (keyframes.h): keys reproduced exactly, slerp / linear in between,
// easing, holding outside the keys, pivots, and every bad timeline named.
#include "engine/deform/keyframes.h"
#include "engine/mesh/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace hdeform {
namespace {

HandleTransform moved(Eigen::Vector3d t, double angle_z = 0, double scale = 1) {
  HandleTransform h;
  h.translation = t;
  h.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(angle_z, Eigen::Vector3d::UnitZ()));
  h.stretch = scale * Eigen::Matrix3d::Identity();
  return h;
}

std::vector<Keyframe> two_keys() {
  return {{0.5, {moved({0, 0, 0}), moved({1, 0, 0})}},
          {2.5, {moved({2, 0, 0}, std::numbers::pi / 2, 3), moved({1, 4, 0})}}};
}

const std::vector<Eigen::Vector3d> kPivots = {{0, 0, 1}, {5, 5, 5}};

TEST(Keyframes, KeysAreReproducedExactlyWithTheirRestPivot) {
  const auto keys = two_keys();
  for (const auto& k : keys) {
    const auto pose = pose_at(keys, k.time, Easing::linear, kPivots);
    ASSERT_EQ(pose.size(), 2u);
    for (std::size_t j = 0; j < 2; ++j) {
      EXPECT_EQ(pose[j].translation, k.transforms[j].translation);
      EXPECT_EQ(pose[j].stretch, k.transforms[j].stretch);
      EXPECT_EQ(pose[j].rotation.coeffs(), k.transforms[j].rotation.coeffs());
      ASSERT_TRUE(pose[j].pivot.has_value());
      EXPECT_EQ(*pose[j].pivot, kPivots[j]);
    }
  }
}

TEST(Keyframes, HoldsBeforeTheFirstAndAfterTheLastKey) {
  const auto keys = two_keys();
  EXPECT_EQ(pose_at(keys, 0.0, Easing::linear, kPivots)[1].translation, Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(pose_at(keys, 99.0, Easing::smoothstep, kPivots)[1].translation,
            Eigen::Vector3d(1, 4, 0));
}

TEST(Keyframes, LinearInBetweenIsSlerpAndLerp) {
  const auto keys = two_keys();
  const auto pose = pose_at(keys, 1.0, Easing::linear, kPivots);  // u = 0.25
  EXPECT_NEAR((pose[0].translation - Eigen::Vector3d(0.5, 0, 0)).norm(), 0, 1e-15);
  EXPECT_NEAR((pose[0].stretch - 1.5 * Eigen::Matrix3d::Identity()).norm(), 0, 1e-15);
  // A quarter of the way from 0 to 90° about z is 22.5° about z.
  const Eigen::AngleAxisd aa(pose[0].rotation);
  EXPECT_NEAR(aa.angle(), std::numbers::pi / 8, 1e-12);
  EXPECT_NEAR((aa.axis() - Eigen::Vector3d::UnitZ()).norm(), 0, 1e-12);
  EXPECT_NEAR(pose[0].rotation.norm(), 1, 1e-15);
  EXPECT_NEAR((pose[1].translation - Eigen::Vector3d(1, 1, 0)).norm(), 0, 1e-15);
}

TEST(Keyframes, SmoothstepEasesTheParameter) {
  const auto keys = two_keys();
  // u = 0.25 → 0.25² (3 − 0.5) = 0.15625
  const auto pose = pose_at(keys, 1.0, Easing::smoothstep, kPivots);
  EXPECT_NEAR(pose[1].translation.y(), 4 * 0.15625, 1e-15);
  // Symmetric about the middle: u = 0.5 stays 0.5.
  EXPECT_NEAR(pose_at(keys, 1.5, Easing::smoothstep, kPivots)[1].translation.y(), 2, 1e-15);
}

// A key's own easing rules its segment (to the next key); the others keep the timeline's.
TEST(Keyframes, AKeysEasingRulesItsSegmentOnly) {
  auto keys = two_keys();
  keys.push_back({4.5, {moved({2, 0, 0}), moved({1, 8, 0})}});
  keys[0].easing = Easing::smoothstep;
  // First segment (0.5 → 2.5) eased although the timeline is linear: u = 0.25 → 0.15625.
  EXPECT_NEAR(pose_at(keys, 1.0, Easing::linear, kPivots)[1].translation.y(), 4 * 0.15625, 1e-15);
  // Second segment (2.5 → 4.5, y 4 → 8): the timeline's linear, u = 0.25.
  EXPECT_NEAR(pose_at(keys, 3.0, Easing::linear, kPivots)[1].translation.y(), 5, 1e-15);
  // A key that says linear in a smoothstep timeline.
  keys[0].easing.reset();
  keys[1].easing = Easing::linear;
  EXPECT_NEAR(pose_at(keys, 1.0, Easing::smoothstep, kPivots)[1].translation.y(), 4 * 0.15625, 1e-15);
  EXPECT_NEAR(pose_at(keys, 3.0, Easing::smoothstep, kPivots)[1].translation.y(), 5, 1e-15);
}

TEST(Keyframes, SlerpTakesTheShortArc) {
  // q and −q are the same rotation: the midpoint must be the identity's neighbourhood,
  // not a half-turn.
  HandleTransform a, b;
  a.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()));
  b.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()));
  b.rotation.coeffs() *= -1;
  const std::vector<Keyframe> keys = {{0, {a}}, {1, {b}}};
  const auto pose = pose_at(keys, 0.5, Easing::linear, std::vector<Eigen::Vector3d>{{0, 0, 0}});
  EXPECT_NEAR(Eigen::AngleAxisd(pose[0].rotation).angle(), 0, 1e-12);
}

TEST(Keyframes, ExplicitPivotsInterpolate) {
  HandleTransform a, b;
  a.pivot = Eigen::Vector3d(0, 0, 0);
  b.pivot = Eigen::Vector3d(2, 0, 0);
  const std::vector<Keyframe> keys = {{0, {a}}, {1, {b}}};
  const auto pose = pose_at(keys, 0.5, Easing::linear, std::vector<Eigen::Vector3d>{{9, 9, 9}});
  EXPECT_EQ(*pose[0].pivot, Eigen::Vector3d(1, 0, 0));
}

TEST(Keyframes, BadTimelinesAreNamed) {
  auto expect_error = [](std::vector<Keyframe> keys, int handles, const std::string& part) {
    try {
      check_keyframes(keys, handles);
      ADD_FAILURE() << "no error, expected " << part;
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  auto keys = two_keys();
  EXPECT_NO_THROW(check_keyframes(keys, 2));
  expect_error(keys, 3, "keys[0]: 2 transforms for 3 handles");
  keys[1].time = 0.5;
  expect_error(keys, 2, "keys[1]: time");
  keys[1].time = 0.25;
  expect_error(keys, 2, "keys[1]: time 0.25 s must be after the previous key's 0.5 s");
  keys[0].time = -1;
  expect_error(keys, 2, "keys[0]: time -1 s must be finite and ≥ 0");
  keys[0].time = std::nan("");
  expect_error(keys, 2, "keys[0]: time");
  keys = two_keys();
  keys[1].transforms[1].rotation.coeffs() << 0, 0, 0, 2;  // not unit
  expect_error(keys, 2, "keys[1].transforms[1]");
  std::vector<Keyframe> many(kMaxKeyframes + 1);
  for (std::size_t i = 0; i < many.size(); ++i) many[i].time = static_cast<double>(i);
  expect_error(many, 0, "exceed the limit of 256");
}

TEST(Keyframes, SampleTimesEndExactlyAtTheEnd) {
  const auto t = sample_times(0, 2, 24);
  ASSERT_EQ(t.size(), 49u);
  EXPECT_EQ(t.front(), 0);
  EXPECT_EQ(t.back(), 2);
  EXPECT_NEAR(t[1], 1.0 / 24, 1e-15);
  const auto u = sample_times(0.5, 1.51, 10);  // 0.5 … 1.5, then 1.51
  ASSERT_EQ(u.size(), 12u);
  EXPECT_EQ(u.back(), 1.51);
  EXPECT_NEAR(u[10], 1.5, 1e-12);
  EXPECT_EQ(sample_times(3, 3, 24), std::vector<double>{3});
  EXPECT_EQ(sample_count(0, 10, 120), 1201u);
}

}  // namespace
}  // namespace hdeform
