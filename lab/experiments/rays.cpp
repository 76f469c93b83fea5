// The lab's ray experiment: closest-hit rays per second on one thread, our
// default structure and the fastest of a few of ours against Bullet's broad
// phases (rayTest) and Intel Embree, on static worlds and on worlds whose
// movers move between batches of rays (the update counted); and the pair
// time of a world in 1, 4 and 16 layers against Bullet's group/mask.
#include "rays.hpp"

#include <algorithm>
#include <broadphase/ray.hpp>
#include <broadphase/rays.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "budget.hpp"
#include "experiment.hpp"
#include "peers/ray_peers.hpp"
#include "structures.hpp"

namespace broadphase::app {

namespace {

using Clock = std::chrono::steady_clock;

// Our default structure, on one thread as every peer here runs.
const char* const kDefault = "grid-verlet:threads=1";
// Ours that may cast faster than the default: one of each family (the
// trees' front-to-back walks, the grids' 3D-DDA, the hierarchical grid).
const char* const kCandidates[] = {"aabb-tree", "octree", "kdtree", "grid-hashed", "hgrid"};
// The batch: the movers move between batches of this many rays.
constexpr std::size_t kBatch = 10000;

struct Kind {
  const char* label;
  Distribution dist;
};
// Uniform spheres at the study's density (the scaled kind keeps it at every
// size), Gaussian clusters, boxes of every shape, half boxes and half
// spheres, and a city of touching buildings under flying spheres.
constexpr Kind kKinds[] = {{"uniform", Distribution::scaled_even},
                           {"clustered", Distribution::clusters},
                           {"boxes", Distribution::boxes},
                           {"mixed", Distribution::half_boxes},
                           {"city", Distribution::city}};

std::string fmt(double v, int digits = 3) {
  if (!std::isfinite(v)) return "–";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}
std::string count_text(double v) {
  if (!std::isfinite(v) || v <= 0) return "–";
  char buf[64];
  if (v >= 1e6)
    std::snprintf(buf, sizeof buf, "%.2fM", v / 1e6);
  else if (v >= 1e3)
    std::snprintf(buf, sizeof buf, "%.1fk", v / 1e3);
  else
    std::snprintf(buf, sizeof buf, "%.0f", v);
  return buf;
}

/// The box holding every object's bounds and the scene's cube (a city wider
/// than its cube stands outside it): rays start inside it.
Aabb world_box(const Scene& s) {
  Aabb b{{0, 0, 0}, {s.world, s.world, s.world}};
  for (const Shape& o : s.objects) {
    const Aabb a = bounds(o);
    for (int k = 0; k < 3; ++k) {
      b.lo[k] = std::min(b.lo[k], a.lo[k]);
      b.hi[k] = std::max(b.hi[k], a.hi[k]);
    }
  }
  return b;
}

/// Random rays: origins uniform in the box, directions uniform on the sphere.
std::vector<Ray> random_rays(const Aabb& box, std::size_t count, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Ray> rays(count);
  for (Ray& r : rays) {
    r.origin = {rng.uniform(box.lo.x, box.hi.x), rng.uniform(box.lo.y, box.hi.y),
                rng.uniform(box.lo.z, box.hi.z)};
    r.dir = rng.direction();
  }
  return rays;
}

/// A lidar's fan from the box's centre (y is up): 64 beams from 45° below
/// the horizon to 15° above, swept round in equal steps of azimuth.
std::vector<Ray> lidar_rays(const Aabb& box, std::size_t count) {
  constexpr std::size_t kBeams = 64;
  const std::size_t steps = std::max<std::size_t>(1, count / kBeams);
  const Vec3 o = (box.lo + box.hi) * 0.5;
  std::vector<Ray> rays;
  rays.reserve(count);
  for (std::size_t k = 0; rays.size() < count; ++k) {
    const double az =
        2 * std::numbers::pi * static_cast<double>(k / kBeams) / static_cast<double>(steps);
    const double el =
        (-45 + 60 * static_cast<double>(k % kBeams) / (kBeams - 1)) * std::numbers::pi / 180;
    Ray r;
    r.origin = o;
    r.dir = {std::cos(el) * std::cos(az), std::sin(el), std::cos(el) * std::sin(az)};
    rays.push_back(r);
  }
  return rays;
}

/// The contract's closest hit by testing every object (the oracle).
PeerHit brute_hit(const std::vector<Shape>& shapes, const Ray& r) {
  return closest_by_testing_all(shapes, r);
}

/// One thing that casts rays into a world: a structure of the registry
/// (ours or Bullet's) or a ray peer (Embree).
class Caster {
 public:
  virtual ~Caster() = default;
  virtual PeerHit cast(const Ray& r) = 0;
  /// Casts rays[k] into out[k] for every k: a ray at a time, or through the
  /// contender's own call for many rays when it has one.
  virtual void cast_batch(std::span<const Ray> rays, std::span<PeerHit> out) {
    for (std::size_t k = 0; k < rays.size(); ++k) out[k] = cast(rays[k]);
  }
  /// Moves objects `ids` to `shapes`, leaving the world ready to cast.
  virtual void move(const std::vector<std::uint32_t>& ids, const std::vector<Shape>& shapes) = 0;
};

class StructureCaster final : public Caster {
 public:
  StructureCaster(const std::string& spec, const Scene& scene, const Aabb& box, bool bulk)
      : bulk_(bulk) {
    Config c;
    c.world = box;
    c.expected_objects = scene.size();
    s_ = registry().make(spec, c);
    handles_.reserve(scene.size());
    for (std::size_t i = 0; i < scene.size(); ++i)
      handles_.push_back(
          s_->insert(scene.objects[i], i, scene.is_moving(i) ? Motion::dynamic : Motion::fixed));
    s_->settle();
  }
  PeerHit cast(const Ray& r) override { return peer_hit(s_->closest_hit(r)); }
  /// Our call for a batch of closest hits (cast_rays, one thread), which a
  /// structure may serve walking several rays at once.
  void cast_batch(std::span<const Ray> rays, std::span<PeerHit> out) override {
    hits_.resize(rays.size());
    broadphase::cast_rays(*s_, rays, hits_, 1);
    for (std::size_t k = 0; k < rays.size(); ++k) out[k] = peer_hit(hits_[k]);
  }
  void move(const std::vector<std::uint32_t>& ids, const std::vector<Shape>& shapes) override {
    if (bulk_) {
      moves_.clear();
      for (std::size_t k = 0; k < ids.size(); ++k) moves_.push_back({handles_[ids[k]], shapes[k]});
      s_->update(moves_);
      s_->settle();
    } else {
      for (std::size_t k = 0; k < ids.size(); ++k) s_->update(handles_[ids[k]], shapes[k]);
    }
  }

 private:
  PeerHit peer_hit(const RayHit& h) const {
    if (h.handle.is_null()) return {};
    return {static_cast<std::int64_t>(s_->user_data(h.handle)), h.t};
  }

  std::unique_ptr<AnyBroadPhase> s_;
  std::vector<Handle> handles_;
  std::vector<Move> moves_;
  std::vector<RayHit> hits_;
  bool bulk_;
};

class PeerCaster final : public Caster {
 public:
  PeerCaster(const RayPeer& p, const Scene& scene, const Aabb& box, bool moving)
      : w_(p.make(scene.objects, box, moving)) {}
  PeerHit cast(const Ray& r) override { return w_->closest_hit(r); }
  void move(const std::vector<std::uint32_t>& ids, const std::vector<Shape>& shapes) override {
    w_->move(ids, shapes);
  }

 private:
  std::unique_ptr<RayWorld> w_;
};

/// A contender of one cell: what it is, and how to build it.
struct Contender {
  std::string name;
  std::string role;  // default, fastest-ours, peer
  bool peer = false;
  bool exact = true;
  std::function<std::unique_ptr<Caster>(const Scene&, const Aabb&, bool moving)> make;
};

Contender structure_contender(const std::string& spec, const std::string& role) {
  const bool peer = registry().find(spec.substr(0, spec.find(':'))) != nullptr &&
                    registry().find(spec.substr(0, spec.find(':')))->peer;
  // Bullet keeps its trees ready for rays with setAabb on each mover (its
  // bulk update would also find every pair, which a ray cast never needs);
  // ours take the bulk update, their way of keeping ready.
  return {spec, role, peer, true, [spec, peer](const Scene& s, const Aabb& b, bool) {
            return std::unique_ptr<Caster>(std::make_unique<StructureCaster>(spec, s, b, !peer));
          }};
}

/// One ray set's measurement of one contender.
struct SetResult {
  std::size_t cast = 0;       // rays timed
  double cast_seconds = 0;    // their time
  std::size_t batches = 0;    // moving: updates timed before this set's batches
  double update_seconds = 0;  // their time
  std::size_t per_batch = 0;  // moving: rays cast after each update (at most kBatch)
  std::size_t checked = 0, mismatches = 0;
  std::string example;  // the first mismatch, for the report

  double per_ray() const { return cast ? cast_seconds / static_cast<double>(cast) : 0; }
  /// Rays per second; moving: a batch of kBatch rays with its update, from
  /// the mean update and the mean ray (the same as measured when whole
  /// batches were cast, a model when the time share cut them: `modelled`).
  double rate(bool moving) const {
    if (cast == 0) return 0;
    if (!moving) return static_cast<double>(cast) / cast_seconds;
    const double upd = batches ? update_seconds / static_cast<double>(batches) : 0;
    return static_cast<double>(kBatch) / (upd + static_cast<double>(kBatch) * per_ray());
  }
  bool modelled() const { return batches > 0 && per_batch < kBatch; }
};

struct CellResult {
  std::string kind;
  std::size_t n = 0;
  bool moving = false;
  double moving_fraction = 0;
  std::string name, role;
  bool peer = false, exact = true;
  double build_ms = 0;
  SetResult sets[2];  // random, lidar
  std::string error;
};

const char* const kSetNames[2] = {"random", "lidar"};

/// Checks the first rays of a set against the oracle's hits: the object and
/// t bit for bit, or only the object for a contender whose t is float; the
/// sample cast one ray at a time and as a batch.
void check_sample(Caster& c, const std::vector<Ray>& rays, const std::vector<PeerHit>& want,
                  bool exact, SetResult& r) {
  std::vector<PeerHit> batch(want.size());
  c.cast_batch(std::span(rays).first(want.size()), batch);
  for (std::size_t j = 0; j < 2 * want.size(); ++j) {
    const std::size_t k = j % want.size();
    const bool one = j < want.size();
    const PeerHit got = one ? c.cast(rays[k]) : batch[k];
    ++r.checked;
    if (got.id == want[k].id && (got.id < 0 || !exact || got.t == want[k].t)) continue;
    if (r.mismatches++ == 0) {
      char buf[240];
      std::snprintf(buf, sizeof buf, "ray %zu (%s): %lld at t=%.17g, oracle %lld at t=%.17g", k,
                    one ? "cast alone" : "in a batch", static_cast<long long>(got.id), got.t,
                    static_cast<long long>(want[k].id), want[k].t);
      r.example = buf;
    }
  }
}

/// The least time a contender casts a set (or a batch) for, whatever is
/// left of its share: 16 rays of Embree take a few microseconds, too few
/// for a rate (one cell's 16-ray rates varied 100-fold), where this much
/// gives thousands.
double floor_seconds(bool quick) { return quick ? 0.002 : 0.05; }

/// Casts rays [from, from + count) of a set in batches (Caster::cast_batch),
/// stopping early once `seconds` have gone (16 rays at least); returns the
/// rays cast.
std::size_t cast_rays(Caster& c, const std::vector<Ray>& rays, std::size_t from, std::size_t count,
                      double seconds, SetResult& r) {
  std::vector<Ray> part;
  std::vector<PeerHit> hits;
  const auto t0 = Clock::now();
  std::size_t k = 0;
  double spent = 0;
  // A sink the compiler cannot drop.
  volatile std::int64_t sink = 0;
  // The clock is read after each batch: 16 rays first (one read costs
  // about a ray of Embree; a slow contender's 16 rays may take the whole
  // share), then up to twice as many each time, at most 1 024 (so that a
  // batch walk has rays to overlap) and at most what the time left holds
  // at the rate so far (16 at least).
  std::size_t batch = 16;
  while (k < count) {
    const std::size_t end = std::min(count, k + batch);
    part.clear();
    for (std::size_t i = k; i < end; ++i) part.push_back(rays[(from + i) % rays.size()]);
    hits.resize(part.size());
    c.cast_batch(part, hits);
    for (const PeerHit& h : hits) sink = sink + h.id;
    k = end;
    spent = std::chrono::duration<double>(Clock::now() - t0).count();
    if (spent > seconds) break;
    const double fits = (seconds - spent) / spent * static_cast<double>(k);
    batch = std::clamp<std::size_t>(
        static_cast<std::size_t>(std::min(fits, static_cast<double>(2 * batch))), 16, 1024);
  }
  r.cast += k;
  r.cast_seconds += spent;
  return k;
}

/// The scene's movers and the shapes they take after one step.
struct Moved {
  std::vector<std::uint32_t> ids;
  std::vector<Shape> shapes;
};
Moved movers_after_step(Scene& s) {
  step(s);
  Moved m;
  for (std::uint32_t i = 0; i < s.size(); ++i)
    if (s.is_moving(i)) {
      m.ids.push_back(i);
      m.shapes.push_back(s.objects[i]);
    }
  return m;
}

/// Measures one contender in one cell within `seconds`.
CellResult measure(const Contender& ct, const Scene& scene, const Aabb& box, bool moving,
                   const std::vector<Ray> (&rays)[2], const std::vector<PeerHit> (&want)[2],
                   double seconds, double floor) {
  CellResult res;
  res.name = ct.name;
  res.role = ct.role;
  res.peer = ct.peer;
  res.exact = ct.exact;
  const auto start = Clock::now();
  auto left = [&] { return seconds - lab_seconds_since(start); };
  try {
    const auto b0 = Clock::now();
    std::unique_ptr<Caster> c = ct.make(scene, box, moving);
    res.build_ms = 1e3 * std::chrono::duration<double>(Clock::now() - b0).count();
    if (!moving) {
      for (int s = 0; s < 2; ++s) check_sample(*c, rays[s], want[s], ct.exact, res.sets[s]);
      for (int s = 0; s < 2; ++s)
        cast_rays(*c, rays[s], want[s].size(), rays[s].size(), std::max(floor, left() / (2 - s)),
                  res.sets[s]);
      return res;
    }
    // Moving: the check after the first step (the oracle's state), then
    // batches alternating between the two sets, each after a step.
    Scene sc = scene;
    Moved m = movers_after_step(sc);
    auto u0 = Clock::now();
    c->move(m.ids, m.shapes);
    double first_update = std::chrono::duration<double>(Clock::now() - u0).count();
    for (int s = 0; s < 2; ++s) check_sample(*c, rays[s], want[s], ct.exact, res.sets[s]);
    std::size_t next[2] = {want[0].size(), want[1].size()};
    // At least two batches per set, at most ten (a set's 10^5 rays).
    const std::size_t max_batches = std::max<std::size_t>(2, rays[0].size() / kBatch);
    for (std::size_t b = 0; b < 2 * max_batches; ++b) {
      const int s = static_cast<int>(b % 2);
      SetResult& r = res.sets[s];
      if (b > 0) {
        m = movers_after_step(sc);
        u0 = Clock::now();
        c->move(m.ids, m.shapes);
        first_update = std::chrono::duration<double>(Clock::now() - u0).count();
      }
      r.update_seconds += first_update;
      ++r.batches;
      // This batch's share of what is left.
      const double share = std::max(floor / 2, left() / static_cast<double>(2 * max_batches - b));
      const std::size_t cast = cast_rays(*c, rays[s], next[s], kBatch, share, r);
      next[s] += cast;
      r.per_batch = r.batches == 1 ? cast : std::min(r.per_batch, cast);
      if (b >= 3 && left() <= 0) break;
    }
  } catch (const std::exception& e) {
    res.error = e.what();
  }
  return res;
}

double cell_weight(std::size_t n) {
  if (n <= 2000) return 1;
  if (n <= 20000) return 1.5;
  if (n <= 200000) return 3;
  return 10;
}
// Below this share a cell is left out (said in the report): the builds of
// its contenders and the oracle's sample alone would take it.
double least_share(std::size_t n) {
  if (n <= 20000) return 0.3;
  if (n <= 200000) return 4;
  return 20;
}

/// The layers part: pair time of `spec` on a world in `layers` layers.
struct LayerResult {
  int layers = 0;
  std::string name;
  std::size_t frames = 0;
  double median_ms = 0;
  std::size_t pairs = 0, want_pairs = 0;
  bool agree = false;
  std::string error;
};

/// Layer `i % layers`; layer 0 is the ground every layer pairs with, the
/// others pair only with themselves and the ground (debris ignores debris
/// of another layer).
Filter layer_filter(std::size_t i, int layers) {
  if (layers == 1) return {};
  const std::uint32_t layer = static_cast<std::uint32_t>(i % static_cast<std::size_t>(layers));
  const std::uint32_t group = 1u << layer;
  return {group, layer == 0 ? 0xffffffffu : (group | 1u)};
}

/// The pairs of a scene's objects that overlap and pass the filters, by
/// testing every pair: the oracle of the layers part.
std::vector<std::pair<std::uint32_t, std::uint32_t>> brute_pairs(const Scene& s, int layers) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  std::vector<Aabb> b(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) b[i] = bounds(s.objects[i]);
  for (std::uint32_t i = 0; i < s.size(); ++i)
    for (std::uint32_t j = i + 1; j < s.size(); ++j)
      if (b[i].overlaps(b[j]) && filters_pass(layer_filter(i, layers), layer_filter(j, layers)) &&
          overlaps(s.objects[i], s.objects[j]))
        out.emplace_back(i, j);
  return out;
}

LayerResult measure_layers(const std::string& spec, const Scene& scene, int layers, int frames,
                           double seconds) {
  LayerResult r;
  r.layers = layers;
  r.name = spec;
  const auto start = Clock::now();
  try {
    Config c;
    c.world = world_box(scene);
    c.expected_objects = scene.size();
    std::unique_ptr<AnyBroadPhase> s = registry().make(spec, c);
    std::vector<Handle> handles;
    for (std::size_t i = 0; i < scene.size(); ++i)
      handles.push_back(s->insert(scene.objects[i], i,
                                  scene.is_moving(i) ? Motion::dynamic : Motion::fixed,
                                  layer_filter(i, layers)));
    s->settle();
    Scene sc = scene;
    std::vector<double> ms;
    std::vector<HandlePair> pairs;
    std::vector<Move> moves;
    for (int f = 0; f < frames; ++f) {
      const Moved m = movers_after_step(sc);
      moves.clear();
      for (std::size_t k = 0; k < m.ids.size(); ++k)
        moves.push_back({handles[m.ids[k]], m.shapes[k]});
      pairs.clear();
      const auto t0 = Clock::now();
      s->update(moves);
      s->find_pairs(pairs);
      ms.push_back(1e3 * std::chrono::duration<double>(Clock::now() - t0).count());
      if (f == 0) {
        // Checked on the first frame, against every pair tested.
        std::vector<std::pair<std::uint32_t, std::uint32_t>> got;
        for (const HandlePair& p : pairs) {
          auto a = static_cast<std::uint32_t>(s->user_data(p.a));
          auto b = static_cast<std::uint32_t>(s->user_data(p.b));
          got.emplace_back(std::min(a, b), std::max(a, b));
        }
        std::sort(got.begin(), got.end());
        const auto want = brute_pairs(sc, layers);
        r.want_pairs = want.size();
        r.pairs = got.size();
        r.agree = got == want;
      }
      if (f >= 2 && lab_seconds_since(start) > seconds) break;
    }
    // The first frame after the inserts warms up: left out when others ran.
    if (ms.size() > 2) ms.erase(ms.begin());
    r.frames = ms.size();
    std::sort(ms.begin(), ms.end());
    r.median_ms = ms[ms.size() / 2];
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  return r;
}

}  // namespace

std::string lab_rays_with(const LabContext& ctx, const RaysOptions& options) {
  const auto start = Clock::now();
  const Registry& reg = registry();
  const std::vector<RayPeer> ray_peers_built = ray_peers();
  std::vector<std::size_t> sizes = options.sizes;
  if (sizes.empty())
    sizes = ctx.quick ? std::vector<std::size_t>{300, 1000}
                      : std::vector<std::size_t>{1000, 10000, 100000, 1000000};
  if (std::erase_if(sizes, [&](std::size_t n) { return n > ctx.max_n; }) && sizes.empty())
    sizes.push_back(ctx.max_n);
  std::vector<Kind> kinds;
  for (const Kind& k : kKinds)
    if (options.kinds.empty() ||
        std::find(options.kinds.begin(), options.kinds.end(), k.label) != options.kinds.end())
      kinds.push_back(k);
  const std::size_t n_rays = options.rays ? options.rays : ctx.quick ? 500 : 100000;
  // The layers part gets a tenth of the budget.
  const double layers_seconds = options.layers ? ctx.budget_seconds * 0.1 : 0;

  std::vector<std::string> bullet;
  for (const char* p : {"bullet-dbvt", "bullet-sweep32"})
    if (reg.find(p) != nullptr) bullet.emplace_back(p);
  std::vector<std::string> candidates;
  for (const char* c : kCandidates)
    if (reg.find(c) != nullptr) candidates.emplace_back(c);

  struct Cell {
    Kind kind;
    std::size_t n;
    bool moving;
  };
  std::vector<Cell> cells;
  for (std::size_t n : sizes)
    for (const Kind& k : kinds)
      for (bool moving : {false, true}) cells.push_back({k, n, moving});
  double weight_total = 0;
  for (const Cell& c : cells) weight_total += cell_weight(c.n);
  double weight_done = 0;
  std::vector<std::string> cuts;
  std::vector<std::string> sweep_left_out;  // cells whose share was too small for Bullet's sweep
  std::vector<CellResult> results;
  // The fastest of ours per kind and size, found on the static cell.
  std::string fastest;

  for (const Cell& cell : cells) {
    const double w = cell_weight(cell.n);
    const double left = ctx.budget_seconds - layers_seconds - lab_seconds_since(start);
    const double share = std::max(0.0, left) * w / std::max(1e-9, weight_total - weight_done);
    weight_done += w;
    const std::string label = std::string(cell.kind.label) + " " + std::to_string(cell.n) +
                              (cell.moving ? " moving" : " static");
    // A quick run keeps its budget too (the lab's test runs one on a clock
    // made six times slower): a cell of its small sizes needs about 0.1 s.
    if (share < (ctx.quick ? 0.1 : least_share(cell.n))) {
      cuts.push_back("left out " + label + " (" + fmt(share, 1) + " s were left for it)");
      continue;
    }
    if (ctx.progress) ctx.progress("rays: " + label, weight_done / weight_total);
    const auto cell_start = Clock::now();
    const Scene scene = generate(cell.kind.dist, cell.n, ctx.seed);
    const Aabb box = world_box(scene);
    const std::vector<Ray> rays[2] = {random_rays(box, n_rays, ctx.seed ^ 0x5241u),
                                      lidar_rays(box, n_rays)};
    // The oracle's sample: its cost grows with n, so fewer rays at a
    // million objects (64 rays of a set are 1.3e8 tests there).
    const std::size_t sample = std::min<std::size_t>(n_rays / 4, ctx.quick          ? 20
                                                                 : cell.n <= 10000  ? 1000
                                                                 : cell.n <= 100000 ? 256
                                                                                    : 64);
    std::vector<PeerHit> want[2];
    {
      Scene state = scene;
      if (cell.moving) movers_after_step(state);
      for (int s = 0; s < 2; ++s)
        for (std::size_t k = 0; k < sample; ++k)
          want[s].push_back(brute_hit(state.objects, rays[s][k]));
    }
    double moving_fraction = 0;
    for (std::size_t i = 0; i < scene.size(); ++i) moving_fraction += scene.is_moving(i);
    moving_fraction /= static_cast<double>(std::max<std::size_t>(1, scene.size()));

    std::vector<Contender> contenders{structure_contender(kDefault, "default")};
    // The fastest of ours: each candidate casts the first random rays
    // after the oracle's sample within a fifth of the cell's share (on the
    // static cell; the moving cell of the same kind and size takes its pick).
    if (!cell.moving) {
      fastest.clear();
      double best_rate = 0;
      const double probe = 0.2 * (share - lab_seconds_since(cell_start)) /
                           static_cast<double>(std::max<std::size_t>(1, candidates.size()));
      for (const std::string& cand : candidates) {
        const Contender ct = structure_contender(cand, "fastest-ours");
        const auto p0 = Clock::now();
        try {
          std::unique_ptr<Caster> c = ct.make(scene, box, false);
          SetResult r;
          // At least the floor of casting after the build: a build that took
          // the whole probe left 16 cold rays, and on a loaded host the
          // kdtree (ten times the aabb-tree's rate) lost the pick so.
          const double rest = std::max(floor_seconds(ctx.quick), probe - lab_seconds_since(p0));
          cast_rays(*c, rays[0], sample, std::min<std::size_t>(2000, n_rays), rest, r);
          if (r.rate(false) > best_rate) {
            best_rate = r.rate(false);
            fastest = cand;
          }
        } catch (const std::exception&) {
          // A candidate that fails is left out of the pick; the default's
          // row reports failures of ours.
        }
      }
    }
    if (!fastest.empty()) contenders.push_back(structure_contender(fastest, "fastest-ours"));
    for (const std::string& spec : options.structures)
      contenders.push_back(structure_contender(spec, "asked"));
    for (const std::string& b : bullet) {
      // Bullet's sweep inserts in O(n) a proxy (its edges move along the
      // axes): minutes at 10^5 objects and more, so only with a generous share.
      if (b == "bullet-sweep32" && cell.n > 20000 && share < 120) {
        sweep_left_out.push_back(label);
        continue;
      }
      contenders.push_back(structure_contender(b, "peer"));
    }
    for (const RayPeer& p : ray_peers_built)
      contenders.push_back(
          {p.name, "peer", true, p.exact, [&p](const Scene& s, const Aabb& b, bool moving) {
             return std::unique_ptr<Caster>(std::make_unique<PeerCaster>(p, s, b, moving));
           }});
    for (std::size_t k = 0; k < contenders.size(); ++k) {
      if (ctx.progress)
        ctx.progress("rays: " + label + " " + contenders[k].name, weight_done / weight_total);
      const double rest = share - lab_seconds_since(cell_start);
      const double seconds = std::max(0.0, rest) / static_cast<double>(contenders.size() - k);
      CellResult r = measure(contenders[k], scene, box, cell.moving, rays, want, seconds,
                             floor_seconds(ctx.quick));
      r.kind = cell.kind.label;
      r.n = cell.n;
      r.moving = cell.moving;
      r.moving_fraction = moving_fraction;
      results.push_back(std::move(r));
    }
  }

  // The layers part.
  std::vector<LayerResult> layer_rows;
  const std::size_t n_layers = ctx.capped(ctx.quick ? 1000 : 10000);
  if (options.layers) {
    const Scene scene = generate(Distribution::scaled_even, n_layers, ctx.seed);
    std::vector<std::string> specs{kDefault};
    for (const std::string& b : bullet) specs.push_back(b);
    const double each = std::max(0.0, ctx.budget_seconds - lab_seconds_since(start)) /
                        static_cast<double>(3 * specs.size());
    for (int layers : {1, 4, 16})
      for (const std::string& spec : specs) {
        if (ctx.progress) ctx.progress("rays: layers " + std::to_string(layers) + " " + spec, 1.0);
        layer_rows.push_back(measure_layers(spec, scene, layers, ctx.quick ? 4 : 30, each));
      }
  }

  // rays.csv and layers.csv.
  {
    std::ofstream csv(ctx.out_dir / "rays.csv");
    csv << "kind,n,world,rays,structure,role,peer,exact,build_ms,rays_cast,rays_per_s,"
           "update_ms,rays_per_batch,modelled,moving_fraction,checked,mismatches,error\n";
    for (const CellResult& r : results)
      for (int s = 0; s < 2; ++s) {
        const SetResult& x = r.sets[s];
        csv << r.kind << ',' << r.n << ',' << (r.moving ? "moving" : "static") << ','
            << kSetNames[s] << ',' << r.name << ',' << r.role << ',' << (r.peer ? 1 : 0) << ','
            << (r.exact ? 1 : 0) << ',' << r.build_ms << ',' << x.cast << ','
            << (r.error.empty() ? x.rate(r.moving) : 0.0) << ','
            << (x.batches ? 1e3 * x.update_seconds / static_cast<double>(x.batches) : 0.0) << ','
            << x.per_batch << ',' << (x.modelled() ? 1 : 0) << ',' << r.moving_fraction << ','
            << x.checked << ',' << x.mismatches << ",\"" << r.error << "\"\n";
      }
  }
  {
    std::ofstream csv(ctx.out_dir / "layers.csv");
    csv << "layers,n,structure,frames,median_frame_ms,pairs,oracle_pairs,agree,error\n";
    for (const LayerResult& r : layer_rows)
      csv << r.layers << ',' << n_layers << ',' << r.name << ',' << r.frames << ',' << r.median_ms
          << ',' << r.pairs << ',' << r.want_pairs << ',' << (r.agree ? "yes" : "no") << ",\""
          << r.error << "\"\n";
  }
  // The report.
  std::ostringstream md;
  md << "## Rays\n\n";
  md << "Closest hit on one thread, rays per second (higher is better), each contender's rays "
        "cast in batches of up to 1 024 through its own call for many rays (ours `cast_rays`, "
        "where the k-d tree and the AABB tree walk eight rays at once from 2^15 objects; "
        "Bullet and Embree a ray at a time, Embree's one-ray path): `"
     << kDefault << "` (ours, the default structure), the fastest of ours among `";
  for (std::size_t k = 0; k < candidates.size(); ++k) md << (k ? "`, `" : "") << candidates[k];
  md << "` on each kind and size (each casts the same " << std::min<std::size_t>(2000, n_rays)
     << " rays at most, within a fifth of the cell's time), Bullet's `btDbvtBroadphase::rayTest` "
        "and `bt32BitAxisSweep3::rayTest` (through its dbvt, the \"accelerator\": without it "
        "Bullet hands every proxy to the callback) with our exact test in the callback and "
        "`m_lambda_max` clipped to the closest hit, and Intel Embree 3";
  if (ray_peers_built.empty()) md << " (**not in this build**: libembree-dev was not found)";
  md << ". `embree` is Embree's BVH over user geometry with our exact double test in its "
        "intersect callback (the contract's answers, bit for bit): it is the one the ratios "
        "use; `embree-native` puts spheres in Embree's own float sphere primitive, its raw "
        "speed, whose answers differ where float rounding moves a hit (counted in the "
        "mismatches column, not a failure).\n\n";
  md << "Worlds: " << n_rays
     << " rays per set (*random*: origins uniform in the box holding the "
        "scene, directions uniform; *lidar*: a fan of 64 beams from 45° below to 15° above the "
        "horizon swept round from the box's centre); kinds *uniform* (spheres at the study's "
        "density, scaled-even), *clustered* (clusters), *boxes*, *mixed* (half_boxes) and "
        "*city* (city: touching buildings, 30% flying spheres as its movers). *Static*: the "
        "rays cast into the built world. *Moving*: the scene's movers (20%; the city's flyers, "
        "30%) step between batches of "
     << kBatch
     << " rays, alternately of each set, and the update counts: ours their bulk update "
        "(`update` of the moves and `settle`), Bullet `setAabb` on each mover, Embree a new "
        "commit of the geometry and `rtcCommitScene` (a dynamic scene, low build quality, one "
        "thread). Where the time share did not allow whole batches, the rate is the mean "
        "update plus "
     << kBatch
     << " times the mean ray (marked *m*). Every contender's closest hit (id and t) is "
        "compared with the oracle's (every object tested) on the first rays of each set "
        "(the moving world after its first step).\n\n";
  md << "Budget: " << fmt(ctx.budget_seconds, 0)
     << " s, shared among the cells (kind × size × static or moving) by their size and again "
        "before each by what was left, and within a cell among its contenders (build, check "
        "and casting: a contender casts rays until its share is spent, so the slow ones cast "
        "fewer), a tenth for the layers part; took "
     << fmt(lab_seconds_since(start), 0) << " s";
  if (!sweep_left_out.empty()) {
    std::string list;
    for (const std::string& l : sweep_left_out) list += (list.empty() ? "" : ", ") + l;
    cuts.push_back(
        "bullet-sweep32 left out above 20 000 objects where a cell had less than 120 s "
        "(its inserts move edges along the axes: minutes at 10^5): " +
        list);
  }
  for (std::size_t c = 0; c < cuts.size(); ++c)
    md << (c ? "; " : ". The budget or the rules ") << cuts[c];
  md << (ctx.quick ? ". **Quick run: small sizes and few rays.**" : ".")
     << " Hardware threads here: " << std::thread::hardware_concurrency()
     << ". CSV: `rays.csv`, `layers.csv`.\n\n";

  auto find_row = [&](const std::string& kind, std::size_t n, bool moving,
                      const std::string& name) -> const CellResult* {
    for (const CellResult& r : results)
      if (r.kind == kind && r.n == n && r.moving == moving && r.name == name) return &r;
    return nullptr;
  };
  std::vector<std::string> names;
  for (const CellResult& r : results)
    if (r.role != "fastest-ours" && std::find(names.begin(), names.end(), r.name) == names.end())
      names.push_back(r.name);
  for (bool moving : {false, true}) {
    md << "**" << (moving ? "Moving world" : "Static world")
       << "**, rays per second (random / lidar); *fastest* names the fastest of ours:\n\n";
    md << "| kind | n | fastest of ours |";
    for (const std::string& n : names) md << ' ' << n << " |";
    md << " " << kDefault << " / bullet-dbvt | " << kDefault << " / embree |\n|---|---:|---|";
    for (std::size_t k = 0; k < names.size() + 2; ++k) md << "---:|";
    md << '\n';
    for (std::size_t n : sizes)
      for (const Kind& kind : kinds) {
        const CellResult* def = find_row(kind.label, n, moving, kDefault);
        if (def == nullptr) continue;
        auto cellText = [&](const CellResult* r) -> std::string {
          if (r == nullptr) return "–";
          if (!r->error.empty()) return "failed: " + r->error;
          std::string t;
          for (int s = 0; s < 2; ++s) {
            const SetResult& x = r->sets[s];
            t += (s ? " / " : "") + count_text(x.rate(moving)) + (x.modelled() ? " *m*" : "");
            if (x.mismatches && r->exact) t += " **" + std::to_string(x.mismatches) + " differ**";
          }
          return t;
        };
        const CellResult* best = nullptr;
        for (const CellResult& r : results)
          if (r.kind == kind.label && r.n == n && r.moving == moving && r.role == "fastest-ours")
            best = &r;
        md << "| " << kind.label << " | " << n << " | "
           << (best ? "`" + best->name + "` " + cellText(best) : "–") << " |";
        for (const std::string& nm : names)
          md << ' ' << cellText(find_row(kind.label, n, moving, nm)) << " |";
        for (const char* peer : {"bullet-dbvt", "embree"}) {
          const CellResult* p = find_row(kind.label, n, moving, peer);
          std::string t = "–";
          if (p != nullptr && p->error.empty() && def->error.empty()) {
            t.clear();
            for (int s = 0; s < 2; ++s)
              t += (s ? " / " : "") + fmt(def->sets[s].rate(moving) / p->sets[s].rate(moving), 2) +
                   "×";
          }
          md << ' ' << t << " |";
        }
        md << '\n';
      }
    md << '\n';
  }
  // The exactness check.
  std::size_t checked = 0, differ = 0;
  std::string first;
  for (const CellResult& r : results)
    for (const SetResult& x : r.sets) {
      if (!r.exact) continue;
      checked += x.checked;
      differ += x.mismatches;
      if (x.mismatches && first.empty())
        first = r.name + " on " + r.kind + " " + std::to_string(r.n) + ": " + x.example;
    }
  md << "Exactness: " << checked << " closest hits of the exact contenders compared with the "
     << "oracle, " << differ << " differ" << (first.empty() ? "" : " (first: " + first + ")")
     << ". `embree-native`'s float t never equals the exact one: its rows in the CSV count "
        "the rays whose closest object differs.\n\n";
  // Drawn with the report's other figures (tools/plot_paper.py finds
  // rays.csv beside results.csv): one Python start instead of two, which
  // is most of a quick run's time here (2-5 s).
  md << "![rays per second](rays.png)\n\n(Drawn by tools/plot_paper.py with the report's "
        "figures; when they are not drawn, `python3 tools/plot_paper.py --rays rays.csv "
        "--out .` draws it from the CSV.)\n\n";

  if (options.layers) {
    md << "**Layers**: the pair time (the movers' bulk update plus every pair, the performance "
          "section's frame) of "
       << n_layers
       << " uniform spheres in 1, 4 and 16 layers (object i in layer i mod L, group 1 << layer; "
          "layer 0 is the ground every layer pairs with, the others pair only with themselves "
          "and the ground), medians over the frames after the first; Bullet gets the same "
          "group and mask in its proxies (its own rule). Pairs of the first frame compared "
          "with every pair tested under `filters_pass`.\n\n";
    md << "| layers | structure | frames | median ms | pairs | oracle's pairs | agree |\n";
    md << "|---:|---|---:|---:|---:|---:|:-:|\n";
    for (const LayerResult& r : layer_rows) {
      if (!r.error.empty()) {
        md << "| " << r.layers << " | " << r.name << " | failed: " << r.error << " | | | | ✗ |\n";
        continue;
      }
      md << "| " << r.layers << " | " << r.name << " | " << r.frames << " | " << fmt(r.median_ms)
         << " | " << r.pairs << " | " << r.want_pairs << " | " << (r.agree ? "✓" : "✗") << " |\n";
    }
    md << '\n';
  }
  if (ctx.progress) ctx.progress("rays", 1.0);
  return md.str();
}

namespace {

std::string lab_rays(const LabContext& ctx) { return lab_rays_with(ctx, {}); }

const RegisterExperiment kRegistered{
    {"rays", 65, "closest-hit rays per second against Bullet and Embree, and layers", lab_rays,
     // Forty cells of five contenders or more and the layers part: the
     // largest of the other experiments' shares would leave out the
     // million-object cells, which two shares keep in a generous run.
     2}};

}  // namespace

}  // namespace broadphase::app
