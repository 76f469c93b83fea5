// The scene reader's tests' shared check: a malformed file is refused with
// a SceneError naming its line. Used by test_scene.cpp and test_scenes_v3.cpp.
#pragma once

#include <gtest/gtest.h>

#include <broadphase/scenes/scene.hpp>
#include <sstream>
#include <string>

namespace broadphase::scene_testing {

// Expects parse_scene to refuse `text` with a message that begins
// "bad.scene:LINE:" and contains `part`; `why` names the case.
inline void expect_rejected(const std::string& text, int line, const std::string& why,
                            const std::string& part = "") {
  std::istringstream in(text);
  try {
    parse_scene(in, "bad.scene");
    ADD_FAILURE() << "accepted: " << why;
  } catch (const SceneError& e) {
    const std::string want = "bad.scene:" + std::to_string(line) + ":";
    EXPECT_EQ(std::string(e.what()).rfind(want, 0), 0u) << why << ": " << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << why << ": " << e.what();
  }
}

}  // namespace broadphase::scene_testing
