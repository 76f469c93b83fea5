// Pictures of a scene, of a structure's cells and of a simulation, rendered
// by tools/draw.py: what `broadphase draw` and the lab's pictures draw.
#pragma once

#include <string>

namespace broadphase::app {

/// What `broadphase draw` draws (see its --help for each field).
struct DrawOptions {
  std::string scene;
  std::string out;
  std::string view = "side";
  std::string algo = "naive";
  bool cells = false;
  int sim_frames = 0;
  bool gif = false;
  bool compare = false;
  std::string ccd = "off";
  double restitution = 1;
  std::string title;
  std::string data;  ///< when set: write the drawing's JSON here instead of rendering it
};

/// Renders one picture through tools/draw.py. Throws UsageError for bad
/// options and std::runtime_error when no picture could be written.
void draw(const DrawOptions& o);

}  // namespace broadphase::app
