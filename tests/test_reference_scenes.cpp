// Every structure reproduces every reference scene exactly, frame by frame.
#include <gtest/gtest.h>

#include "testing.hpp"

namespace broadphase::testing {
namespace {

class ReferenceScenes : public ::testing::TestWithParam<std::string> {};

TEST_P(ReferenceScenes, ReproduceEveryFrame) {
  const auto scenes = reference_scenes();
  ASSERT_GE(scenes.size(), 10u) << "reference scenes missing from " << BROADPHASE_TEST_DATA;
  for (const ReferenceScene& ref : scenes) {
    SCOPED_TRACE(ref.name);
    const Scene scene = read_scene(ref.scene_path);
    const auto got = replay(GetParam(), scene, static_cast<int>(ref.expected.size()), true);
    for (std::size_t f = 0; f < ref.expected.size(); ++f) {
      ASSERT_EQ(got[f].pairs, ref.expected[f].pairs) << "frame " << f;
      ASSERT_EQ(hex16(got[f].hash), hex16(ref.expected[f].hash)) << "frame " << f;
    }
  }
}

TEST_P(ReferenceScenes, MatchBruteForceOnGeneratedStudyScenes) {
  for (Distribution d : {Distribution::even, Distribution::uneven}) {
    Scene scene = generate(d, 1600, 7);
    const auto got = replay(GetParam(), scene, 6);
    for (int f = 0; f < 6; ++f) {
      if (f > 0) step(scene);
      ASSERT_EQ(got[f], brute_force(scene.objects)) << to_string(d) << " frame " << f;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(All, ReferenceScenes, ::testing::ValuesIn(structure_specs()),
                         StructureParamName{});

}  // namespace
}  // namespace broadphase::testing
