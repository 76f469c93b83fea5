// Pictures of a scene (side, top and 3D views), of how a family of
// structures divides it, and of a simulation (strip, GIF, tunneling with and
// without a remedy), for `broadphase draw` and the lab's pictures. This
// file decides what to draw and writes it as JSON; tools/draw.py renders it
// with matplotlib.
#include "draw.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <broadphase/scenes/output_file.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/scenes/sim.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lab.hpp"
#include "structures.hpp"
#include "usage_error.hpp"

namespace broadphase::app {

namespace {

using Json = nlohmann::json;

/// One drawable box: [lo x y z, hi x y z, value] (cells add their level).
Json box_row(const Aabb& b, double value) {
  return Json::array({b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z, value});
}

Aabb world_box(const Scene& s) { return {{0, 0, 0}, {s.world, s.world, s.world}}; }

/// The cells or nodes of `spec` as the structure builds them over the
/// scene's objects (AnyBroadPhase::visit_cells). The picture's kind follows
/// from what the structure reports: one level is a grid (colour: objects per
/// cell); a single cell at the lowest level is the root of a tree (colour:
/// depth); several cells at every level are a hierarchy of grids (colour:
/// level).
Json cells_for(const Scene& s, const std::string& spec) {
  Config c;
  c.world = world_box(s);
  c.expected_objects = s.size();
  std::unique_ptr<AnyBroadPhase> bp;
  try {
    bp = registry().make(spec, c);
  } catch (const std::exception& e) {
    throw UsageError(std::string("--algo: ") + e.what());
  }
  for (std::uint32_t i = 0; i < s.size(); ++i)
    bp->insert(s.objects[i], i, s.is_moving(i) ? Motion::dynamic : Motion::fixed);
  bp->settle();  // the cells a frame reads (grid-verlet: the loose objects into its grids)

  constexpr std::size_t kMaxBoxes = 200000;  // what matplotlib draws in a few seconds
  Json rows = Json::array();
  std::map<int, std::size_t> per_level;
  std::size_t held = 0;
  const bool has = bp->visit_cells([&](const Aabb& box, int level, std::size_t objects) {
    if (rows.size() == kMaxBoxes) return;
    ++per_level[level];
    held += objects;
    rows.push_back(box_row(box, static_cast<double>(objects)));
    rows.back().push_back(level);
  });
  const std::string name = spec.substr(0, spec.find(':'));
  if (!has)
    throw UsageError("--cells: " + name +
                     " has no cells or nodes to draw (it keeps its objects in lists or sorted "
                     "axes, or is another library's)");
  if (rows.size() == kMaxBoxes)
    throw UsageError("--cells: " + spec + " reports more than " + std::to_string(kMaxBoxes) +
                     " cells: too many to draw");
  const char* kind = per_level.size() <= 1            ? "grid"
                     : per_level.begin()->second == 1 ? "tree"
                                                      : "hgrid";
  char label[240];
  if (std::string(kind) == "grid") {
    const double edge = rows.empty() ? 0 : rows[0][3].get<double>() - rows[0][0].get<double>();
    std::snprintf(label, sizeof label,
                  "%s as built: %zu occupied cells of edge %.3g, colour = objects per cell",
                  spec.c_str(), rows.size(), edge);
  } else if (std::string(kind) == "tree") {
    std::snprintf(label, sizeof label, "%s as built: %zu nodes, depth %d to %d, colour = depth",
                  spec.c_str(), rows.size(), per_level.begin()->first, per_level.rbegin()->first);
  } else {
    std::snprintf(label, sizeof label,
                  "%s as built: %zu occupied cells on %zu levels, colour = level", spec.c_str(),
                  rows.size(), per_level.size());
  }
  return {
      {"kind", kind}, {"label", label}, {"spec", spec}, {"objects_held", held}, {"boxes", rows}};
}

Json objects_json(const Scene& s) {
  Json x = Json::array(), y = Json::array(), z = Json::array(), hx = Json::array(),
       hy = Json::array(), hz = Json::array(), box = Json::array(), moving = Json::array(),
       vel = Json::array();
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Shape& o = s.objects[i];
    x.push_back(o.center.x);
    y.push_back(o.center.y);
    z.push_back(o.center.z);
    hx.push_back(o.half.x);
    hy.push_back(o.half.y);
    hz.push_back(o.half.z);
    box.push_back(!o.is_sphere());
    moving.push_back(s.is_moving(i));
    vel.push_back(Json::array({s.velocity[i].x, s.velocity[i].y, s.velocity[i].z}));
  }
  return {{"x", x},   {"y", y},     {"z", z},           {"hx", hx},       {"hy", hy},
          {"hz", hz}, {"box", box}, {"moving", moving}, {"velocity", vel}};
}

/// Runs the simulation and records the movers' centres at every frame.
Json sim_run(const Scene& scene, const std::string& algo, Ccd ccd, double k, int frames) {
  SimConfig c;
  c.ccd = ccd;
  c.restitution = k;
  Config bc;
  bc.world = world_box(scene);
  Simulation sim(scene, registry().make(algo, bc), c);
  std::vector<std::uint32_t> movers;
  for (std::uint32_t i = 0; i < scene.size(); ++i)
    if (scene.is_moving(i)) movers.push_back(i);
  const auto snapshot = [&] {
    Json f = Json::array();
    for (const std::uint32_t i : movers) {
      const Vec3& p = sim.scene().objects[i].center;
      f.push_back(Json::array({p.x, p.y, p.z}));
    }
    return f;
  };
  Json positions = Json::array({snapshot()});
  Json contacts = Json::array();
  std::uint64_t missed = 0, truth = 0, total = 0;
  for (int f = 0; f < frames; ++f) {
    const StepStats st = sim.step();
    missed += st.missed;
    truth += st.true_contacts;
    total += st.contacts;
    contacts.push_back(st.contacts);
    positions.push_back(snapshot());
  }
  return {{"ccd", std::string(to_string(ccd))},
          {"restitution", k},
          {"movers", movers},
          {"positions", positions},
          {"contacts", contacts},
          {"contacts_total", total},
          {"true_contacts", truth},
          {"missed", missed}};
}

}  // namespace

void draw(const DrawOptions& o) {
  const std::string ext = std::filesystem::path(o.out).extension().string();
  if (o.gif ? ext != ".gif" : (ext != ".png" && ext != ".svg"))
    throw UsageError("--out: '" + o.out + "' must end in " + (o.gif ? ".gif" : ".png or .svg"));
  if (o.gif && o.sim_frames == 0) throw UsageError("--gif needs --sim FRAMES");
  if (o.compare && o.sim_frames == 0) throw UsageError("--compare needs --sim FRAMES");
  if (o.view != "side" && o.view != "top" && o.view != "3d")
    throw UsageError("--view: '" + o.view + "' is not one of side, top, 3d");
  Ccd ccd;
  try {
    ccd = parse_ccd(o.ccd);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("--ccd: ") + e.what());
  }
  check_writable_directory(std::filesystem::path(o.out).parent_path());
  const Scene scene = read_scene(o.scene);
  std::size_t movers = 0;
  for (std::size_t i = 0; i < scene.size(); ++i) movers += scene.is_moving(i) ? 1 : 0;
  if (o.sim_frames > 0 && movers * static_cast<std::size_t>(o.sim_frames) > 2000000)
    throw UsageError("--sim: too much to draw (moving objects x frames above 2 million)");

  Json j;
  j["scene"] = std::filesystem::path(o.scene).filename().string();
  j["world"] = scene.world;
  j["view"] = o.view;
  j["title"] = o.title;
  // The script draws under a temporary name, renamed when it is done.
  PendingFile picture(o.out);
  j["out"] = picture.temp().string();
  j["gif"] = o.gif;
  j["algo"] = o.algo;
  j["objects"] = objects_json(scene);
  if (o.cells) j["cells"] = cells_for(scene, o.algo);
  if (o.sim_frames > 0) {
    // The broad phase only finds pairs: the trajectories are the same on
    // every exact structure.
    const std::string& bp = o.algo;
    Json runs = Json::array();
    if (o.compare) {
      runs.push_back(sim_run(scene, bp, Ccd::off, o.restitution, o.sim_frames));
      runs.push_back(
          sim_run(scene, bp, ccd == Ccd::off ? Ccd::swept : ccd, o.restitution, o.sim_frames));
    } else {
      runs.push_back(sim_run(scene, bp, ccd, o.restitution, o.sim_frames));
    }
    j["sim"] = {{"frames", o.sim_frames}, {"compare", o.compare}, {"runs", runs}};
  }

  if (!o.data.empty()) {
    std::ofstream f(o.data);
    if (!(f << j.dump())) throw std::runtime_error("draw: cannot write " + o.data);
    return;
  }
  const std::filesystem::path data = std::filesystem::temp_directory_path() /
                                     ("broadphase-draw-" + std::to_string(::getpid()) + ".json");
  {
    std::ofstream f(data);
    if (!f) throw std::runtime_error("draw: cannot write " + data.string());
    f << j.dump();
  }
  bool ok = false;
  try {
    ok = run_plot_script("draw.py", {data.string()});
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(data, ignored);
    throw;
  }
  std::error_code ignored;
  std::filesystem::remove(data, ignored);
  if (ok) picture.commit();
  if (!ok)
    throw std::runtime_error(
        "draw: no picture written: tools/draw.py needs python3 with "
        "matplotlib (Debian: python3-matplotlib; GIFs also python3-pil)");
}

}  // namespace broadphase::app
