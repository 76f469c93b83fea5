// `draw`: pictures of a scene (side, top and 3D views), of how a family of
// structures divides it, and of a simulation (strip, GIF, tunneling with and
// without a remedy). This file decides what to draw and writes it as JSON;
// tools/draw.py renders it with matplotlib.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <broadphase/lab/output_file.hpp>
#include <broadphase/lab/scene.hpp>
#include <broadphase/lab/sim.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "commands.hpp"
#include "lab.hpp"

namespace broadphase::app {

namespace {

using Json = nlohmann::json;

/// One drawable box: [lo x y z, hi x y z, value].
Json box_row(const Aabb& b, double value) {
  return Json::array({b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z, value});
}

Aabb world_box(const Scene& s) { return {{0, 0, 0}, {s.world, s.world, s.world}}; }

std::map<std::string, std::string> spec_options(const std::string& spec) {
  std::map<std::string, std::string> out;
  const std::size_t colon = spec.find(':');
  if (colon == std::string::npos) return out;
  std::size_t pos = colon + 1;
  while (pos <= spec.size()) {
    std::size_t end = spec.find(',', pos);
    if (end == std::string::npos) end = spec.size();
    const std::string kv = spec.substr(pos, end - pos);
    const std::size_t eq = kv.find('=');
    if (eq != std::string::npos) out[kv.substr(0, eq)] = kv.substr(eq + 1);
    pos = end + 1;
  }
  return out;
}

double option_number(const std::map<std::string, std::string>& opts, const std::string& key,
                     double fallback) {
  const auto it = opts.find(key);
  if (it == opts.end()) return fallback;
  try {
    std::size_t used = 0;
    const double v = std::stod(it->second, &used);
    if (used != it->second.size() || !(v > 0) || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::exception&) {
    throw UsageError("--algo: option " + key + "=" + it->second + " is not a positive number");
  }
}

double largest_extent(const Scene& s) {
  double m = 0;
  for (const Shape& o : s.objects) m = std::max(m, o.max_half());
  return m;
}

/// A uniform grid of cell size `cell` over the world, each occupied cell
/// with the number of objects whose bounds touch it.
Json grid_cells(const Scene& s, double cell) {
  const long n = static_cast<long>(std::ceil(s.world / cell));
  if (n > 200) throw UsageError("--algo: cell size too small to draw (at most 200 cells a side)");
  std::map<std::array<long, 3>, int> count;
  for (const Shape& o : s.objects) {
    const Aabb b = bounds(o);
    std::array<long, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::clamp(static_cast<long>(std::floor(b.lo[a] / cell)), 0L, n - 1);
      hi[a] = std::clamp(static_cast<long>(std::floor(b.hi[a] / cell)), 0L, n - 1);
    }
    for (long x = lo[0]; x <= hi[0]; ++x)
      for (long y = lo[1]; y <= hi[1]; ++y)
        for (long z = lo[2]; z <= hi[2]; ++z) ++count[{x, y, z}];
  }
  Json rows = Json::array();
  for (const auto& [c, k] : count) {
    const Aabb box{{c[0] * cell, c[1] * cell, c[2] * cell},
                   {(c[0] + 1) * cell, (c[1] + 1) * cell, (c[2] + 1) * cell}};
    rows.push_back(box_row(box, k));
  }
  char label[160];
  std::snprintf(label, sizeof label, "uniform grid, cell %.4g: objects per cell", cell);
  return {{"kind", "grid"}, {"label", label}, {"boxes", rows}};
}

/// The octree an object-in-the-smallest-enclosing-node octree builds: a
/// node splits when it holds more than `capacity` objects, down to
/// `max_depth`; objects that straddle a child boundary stay in the parent.
Json octree_cells(const Scene& s, int max_depth, int capacity) {
  Json rows = Json::array();
  struct Node {
    Aabb box;
    int depth;
    std::vector<std::uint32_t> objects;
  };
  std::vector<Node> stack;
  Node root{world_box(s), 0, {}};
  for (std::uint32_t i = 0; i < s.size(); ++i) root.objects.push_back(i);
  stack.push_back(std::move(root));
  while (!stack.empty()) {
    Node node = std::move(stack.back());
    stack.pop_back();
    std::vector<std::uint32_t> kept;
    std::array<std::vector<std::uint32_t>, 8> child;
    const Vec3 mid = (node.box.lo + node.box.hi) * 0.5;
    const bool split = node.depth<max_depth&& static_cast<int>(node.objects.size())> capacity;
    for (const std::uint32_t i : node.objects) {
      const Aabb b = bounds(s.objects[i]);
      int code = 0;
      bool fits = split;
      for (int a = 0; a < 3 && fits; ++a) {
        if (b.hi[a] <= mid[a]) continue;
        if (b.lo[a] >= mid[a])
          code |= 1 << a;
        else
          fits = false;
      }
      if (fits)
        child[code].push_back(i);
      else
        kept.push_back(i);
    }
    rows.push_back(box_row(node.box, node.depth));
    for (int c = 0; c < 8; ++c) {
      if (child[c].empty()) continue;
      Aabb box = node.box;
      for (int a = 0; a < 3; ++a) (c >> a & 1 ? box.lo[a] : box.hi[a]) = mid[a];
      stack.push_back({box, node.depth + 1, std::move(child[c])});
    }
  }
  char label[160];
  std::snprintf(label, sizeof label,
                "octree nodes (depth <= %d, split above %d objects): colour = depth", max_depth,
                capacity);
  return {{"kind", "octree"}, {"label", label}, {"boxes", rows}};
}

/// A hierarchical grid: cell sizes doubling from the smallest diameter;
/// each object lives at the first level whose cell is at least its
/// diameter, in the cell of its centre. Occupied cells, value = level.
Json hgrid_cells(const Scene& s) {
  double smallest = s.world;
  for (const Shape& o : s.objects)
    if (o.max_half() > 0) smallest = std::min(smallest, 2 * o.max_half());
  const double base = std::max(smallest, s.world / 1024);
  std::map<std::array<long, 4>, int> cells;
  for (const Shape& o : s.objects) {
    int level = 0;
    double cell = base;
    while (cell < 2 * o.max_half() && level < 30) {
      cell *= 2;
      ++level;
    }
    std::array<long, 4> key{level, 0, 0, 0};
    for (int a = 0; a < 3; ++a) key[a + 1] = static_cast<long>(std::floor(o.center[a] / cell));
    ++cells[key];
  }
  Json rows = Json::array();
  for (const auto& [k, count] : cells) {
    const double cell = base * std::ldexp(1.0, static_cast<int>(k[0]));
    const Aabb box{{k[1] * cell, k[2] * cell, k[3] * cell},
                   {(k[1] + 1) * cell, (k[2] + 1) * cell, (k[3] + 1) * cell}};
    rows.push_back(box_row(box, static_cast<double>(k[0])));
  }
  char label[160];
  std::snprintf(label, sizeof label,
                "hierarchical grid, level 0 cell %.3g doubling: occupied cells, colour = level",
                base);
  return {{"kind", "hgrid"}, {"label", label}, {"boxes", rows}, {"base", base}};
}

/// The nodes of a bounding-volume tree built top-down by median split on
/// the longest axis of the centres, to depth 4.
Json tree_cells(const Scene& s) {
  Json rows = Json::array();
  std::vector<std::uint32_t> ids(s.size());
  for (std::uint32_t i = 0; i < s.size(); ++i) ids[i] = i;
  struct Range {
    std::size_t lo, hi;
    int depth;
  };
  std::vector<Range> stack{{0, ids.size(), 0}};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    if (r.lo >= r.hi) continue;
    Aabb box = bounds(s.objects[ids[r.lo]]);
    Aabb centres{s.objects[ids[r.lo]].center, s.objects[ids[r.lo]].center};
    for (std::size_t i = r.lo; i < r.hi; ++i) {
      box = box.merged(bounds(s.objects[ids[i]]));
      centres = centres.merged({s.objects[ids[i]].center, s.objects[ids[i]].center});
    }
    rows.push_back(box_row(box, r.depth));
    if (r.depth >= 4 || r.hi - r.lo <= 2) continue;
    const Vec3 ext = centres.hi - centres.lo;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const std::size_t mid = (r.lo + r.hi) / 2;
    std::nth_element(ids.begin() + static_cast<long>(r.lo), ids.begin() + static_cast<long>(mid),
                     ids.begin() + static_cast<long>(r.hi), [&](std::uint32_t a, std::uint32_t b) {
                       return s.objects[a].center[axis] < s.objects[b].center[axis];
                     });
    stack.push_back({r.lo, mid, r.depth + 1});
    stack.push_back({mid, r.hi, r.depth + 1});
  }
  return {{"kind", "tree"},
          {"label", "bounding-volume tree (median split, depth <= 4): colour = depth"},
          {"boxes", rows}};
}

Json cells_for(const Scene& s, const std::string& spec) {
  const std::string name = spec.substr(0, spec.find(':'));
  const auto opts = spec_options(spec);
  const auto has = [&](const char* w) { return name.find(w) != std::string::npos; };
  if (has("octree"))
    return octree_cells(s, static_cast<int>(option_number(opts, "depth", 4)),
                        static_cast<int>(option_number(opts, "capacity", 8)));
  if (has("hgrid") || has("hier") || has("multi")) return hgrid_cells(s);
  if (has("grid") || has("hash")) {
    // By default a cell fits the largest object, and the cells tile the world.
    const double widest = std::max(2 * largest_extent(s), s.world / 64);
    const double fallback = s.world / std::max(1.0, std::floor(s.world / widest));
    return grid_cells(s, option_number(opts, "cell", fallback));
  }
  if (has("tree") || has("bvh") || has("kd")) return tree_cells(s);
  if (name == "naive") throw UsageError("--cells: naive has no cells to draw: it tests every pair");
  throw UsageError("--cells: no cell picture for '" + name +
                   "' (names containing grid, hash, hgrid, octree, tree, bvh or kd can be drawn)");
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
    // The broad phase only finds pairs; the trajectories are the same on
    // every exact structure, so the cells' name need not be a real one.
    const std::string bp = registry().find(o.algo.substr(0, o.algo.find(':'))) ? o.algo : "naive";
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

void add_draw_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "draw",
      "Draw a scene, a structure's cells, or a simulation (PNG, SVG or GIF via matplotlib)");
  auto o = std::make_shared<DrawOptions>();
  cmd->add_option("--scene", o->scene, "Scene file (SCENE-FORMAT.md)")->required();
  cmd->add_option("--out", o->out, "Picture to write: .png or .svg (.gif with --gif)")->required();
  cmd->add_option("--view", o->view, "side (x, y: y is up) | top (x, z) | 3d")->default_val("side");
  cmd->add_option("--algo", o->algo,
                  "Structure whose cells --cells draws (grid:cell=C, hgrid, octree:depth=D, "
                  "tree); also the broad phase of --sim when it is registered")
      ->default_val("naive");
  cmd->add_flag("--cells", o->cells, "Overlay the cells or nodes of --algo");
  cmd->add_option("--sim", o->sim_frames, "Simulate FRAMES steps and draw a strip of them")
      ->check(CLI::Range(1, 100000));
  cmd->add_flag("--gif", o->gif, "With --sim: an animated GIF instead of a strip");
  cmd->add_flag("--compare", o->compare,
                "With --sim: trails with --ccd off beside trails with the remedy (--ccd, "
                "default swept)");
  cmd->add_option("--ccd", o->ccd, "off | substep | swept")->default_val("off");
  cmd->add_option("--restitution", o->restitution, "k in [0, 1] for --sim")
      ->default_val(1)
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--title", o->title, "Title of the picture (a default names the scene)");
  cmd->callback([o] { draw(*o); });
}

}  // namespace broadphase::app
