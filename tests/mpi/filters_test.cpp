// Collision filters over MPI ranks (run under mpiexec -np P, any P): every
// frame's pairs of the whole world, gathered from every rank, must be
// exactly the brute-force pairs with the group/mask rule applied
// (filters_pass of geometry.hpp), each reported once. Worlds of random
// bits, 4 layers and 16 layers; spheres and boxes, a few objects large
// enough to go to the shared list and a few outside the world; objects
// moving, some jumping, and filters changing between frames (static
// objects' too, so a filter must travel without a change of shape).
// Through every entry point: Domain::find_pairs over shapes with group and
// mask spans (grid, then bisection), over an Objects view with filter
// columns, with a registry structure (--algo), and PairTracker with a skin.
// Ownership does not matter for exactness: the Domain runs give each
// object to the owner of its centre, the tracker's to rank id % P, so most
// of their pairs meet across ranks.
//
// Rays over the same worlds, every frame a fresh batch with fresh masks:
// every rank computes the brute-force hits (the world is known to all) and
// checks Domain::all_hits (rows on rank 0, or on every rank), closest_hits
// and any_hits against them, bit for bit; coincident static objects make
// ties of t that the ids decide, often across ranks. Invalid rays, batches
// that differ between ranks and results of the wrong length are refused on
// every rank alike.
//
//   mpiexec -np 3 mpi_filters_test [--seed S] [--seeds K] [--frames F] [--objects N]
//
// Prints the seeds it runs; a failure names the seed, world, entry point,
// frame and the first pairs that differ, and exits non-zero. Every failure
// is agreed by all ranks, so none waits for another.
#include <mpi.h>

#include <algorithm>
#include <broadphase/geometry.hpp>
#include <broadphase/mpi.hpp>
#include <broadphase/ray.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace bd = broadphase::mpi;
using broadphase::Filter;
using broadphase::Ray;
using broadphase::Shape;
using broadphase::Vec3;

namespace {

constexpr double kWorld = 100;

int rank_ = 0, size_ = 1;

struct World {
  std::vector<Shape> shapes;
  std::vector<Vec3> velocity;
  std::vector<Filter> filters;
};

enum class Kind { random_bits, layers4, layers16 };
const char* name(Kind k) {
  return k == Kind::random_bits ? "random-bits" : k == Kind::layers4 ? "4-layers" : "16-layers";
}

// A filter drawn for `kind`: random bits (few group bits over 8, masks of
// any 8 bits, some ruling out everything, some letting everything in), or
// layers that pair with their own layer, now and then a neighbour, and a
// few objects (sensors) that see every layer.
Filter draw_filter(Kind kind, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> pct(0, 99);
  if (kind == Kind::random_bits) {
    const int p = pct(rng);
    if (p < 5) return Filter{};
    if (p < 10) return {static_cast<std::uint32_t>(rng() & 0xff), 0};
    std::uint32_t group = 1u << (rng() % 8);
    if (pct(rng) < 30) group |= 1u << (rng() % 8);
    return {group, static_cast<std::uint32_t>(rng() & 0xff)};
  }
  const int layers = kind == Kind::layers4 ? 4 : 16;
  const auto layer = static_cast<std::uint32_t>(rng() % static_cast<std::uint64_t>(layers));
  Filter f{1u << layer, 1u << layer};
  if (pct(rng) < 20) f.mask |= 1u << ((layer + 1) % static_cast<std::uint32_t>(layers));
  if (pct(rng) < 3) f.mask = 0xffffffffu;
  return f;
}

World make_world(Kind kind, std::size_t n, std::mt19937_64& rng) {
  World w;
  std::uniform_real_distribution<double> pos(0, kWorld), unit(-1, 1), size(0.5, 4);
  std::uniform_int_distribution<int> pct(0, 99);
  std::size_t last_static = n;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 c{pos(rng), pos(rng), pos(rng)};
    const int p = pct(rng);
    if (p >= 96 && last_static < n) {
      // A static copy of a static object: rays hit both at the same t.
      w.shapes.push_back(w.shapes[last_static]);
      w.velocity.push_back({0, 0, 0});
      w.filters.push_back(draw_filter(kind, rng));
      continue;
    }
    if (p < 3) c.x = -20 + unit(rng) * 5;  // outside the world box
    double r = size(rng);
    if (p >= 3 && p < 6) r = 30 + 20 * pct(rng) / 100.0;  // reaches many ranks
    if (pct(rng) < 40)
      w.shapes.push_back(Shape::box(c, {r, r * (0.5 + pct(rng) / 100.0), r * 0.7}));
    else
      w.shapes.push_back(Shape::sphere(c, r));
    const bool moves = pct(rng) < 50;
    w.velocity.push_back(moves ? Vec3{0.3 * unit(rng), 0.3 * unit(rng), 0.3 * unit(rng)}
                               : Vec3{0, 0, 0});
    w.filters.push_back(draw_filter(kind, rng));
    if (!moves) last_static = i;
  }
  return w;
}

// A fresh batch of rays: origins in and around the world, inside objects,
// on the grid's cut planes and far away; directions random, along an axis,
// zero, or aimed at an object (so that most rays hit something); tmax 0,
// finite or infinite; masks of the world's kind, all bits, or none.
std::vector<Ray> draw_rays(const World& w, Kind kind, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> pct(0, 99);
  std::uniform_real_distribution<double> pos(-30, kWorld + 30), unit(-1, 1), reach(0, 300);
  const std::size_t n = 20 + rng() % 40;
  auto some_object = [&] { return w.shapes[rng() % w.shapes.size()].center; };
  std::vector<Ray> rays(n);
  for (Ray& r : rays) {
    const int o = pct(rng);
    r.origin = o < 50   ? Vec3{pos(rng), pos(rng), pos(rng)}
               : o < 70 ? some_object()
               : o < 85 ? Vec3{kWorld / 2, pos(rng), kWorld / 2}
                        : Vec3{1e4 * unit(rng), 1e4 * unit(rng), 1e4 * unit(rng)};
    const int d = pct(rng);
    if (d < 15) {
      r.dir = {0, 0, 0};
      r.dir[static_cast<int>(rng() % 3)] = pct(rng) < 50 ? 1 : -1;
    } else if (d < 20) {
      r.dir = {0, 0, 0};
    } else if (d < 60) {
      const Vec3 c = some_object();
      r.dir = {c.x - r.origin.x, c.y - r.origin.y, c.z - r.origin.z};
      if (!broadphase::is_valid(r)) r.dir = {1, 0, 0};  // aimed from its own centre
    } else {
      const double scale = std::pow(10.0, 4 * unit(rng));
      r.dir = {scale * unit(rng), scale * unit(rng), scale * unit(rng)};
    }
    const int t = pct(rng);
    r.tmax = t < 10 ? 0 : t < 50 ? std::numeric_limits<double>::infinity() : reach(rng) / 100;
    const int m = pct(rng);
    r.mask = m < 10 ? 0xffffffffu : m < 13 ? 0u : draw_filter(kind, rng).mask;
  }
  return rays;
}

// Each ray's brute-force hits by the contract's test (ray.hpp), sorted by
// (t, id).
std::vector<std::vector<bd::IdHit>> oracle_hits(const World& w, const std::vector<Ray>& rays) {
  std::vector<std::vector<bd::IdHit>> rows(rays.size());
  for (std::size_t k = 0; k < rays.size(); ++k) {
    for (std::size_t i = 0; i < w.shapes.size(); ++i) {
      double t = 0;
      if (broadphase::ray_sees(rays[k].mask, w.filters[i]) &&
          broadphase::ray_hit(rays[k], w.shapes[i], t))
        rows[k].push_back({t, static_cast<std::uint32_t>(i), true});
    }
    std::sort(rows[k].begin(), rows[k].end(), [](const bd::IdHit& a, const bd::IdHit& b) {
      return a.t < b.t || (a.t == b.t && a.id < b.id);
    });
  }
  return rows;
}

std::string hit_text(const bd::IdHit& h) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%u at %.17g", h.id, h.t);
  return h.hit ? buf : "none";
}

// What the rays of a run met: hits, rays whose closest hit is a tie of t
// decided by the id, and hits the masks ruled out.
struct RayCounts {
  std::uint64_t hits = 0, ties = 0, masked = 0;
};

// Casts a fresh batch through all_hits (rows on rank 0 or on every rank,
// alternately), closest_hits and any_hits; every rank checks what it
// received against brute force; the verdict is agreed.
void check_rays(bd::Domain& domain, const std::vector<std::uint32_t>& ids,
                const broadphase::Objects& objects, const World& w, Kind kind, int frame,
                std::mt19937_64& rng, const std::string& where, RayCounts& counts) {
  const std::vector<Ray> rays = draw_rays(w, kind, rng);
  const std::vector<std::vector<bd::IdHit>> want = oracle_hits(w, rays);
  const int root = frame % 2 == 0 ? 0 : bd::kEveryRank;
  bd::IdHitRows rows;
  std::vector<bd::IdHit> closest(rays.size());
  std::vector<std::uint8_t> any(rays.size());
  domain.all_hits(ids, objects, rays, rows, root);
  domain.closest_hits(ids, objects, rays, closest);
  domain.any_hits(ids, objects, rays, any);
  std::string error;
  const bool has_rows = root == bd::kEveryRank || root == rank_;
  if (has_rows && rows.offsets.size() != rays.size() + 1)
    error = "all_hits gave " + std::to_string(rows.offsets.size()) + " offsets for " +
            std::to_string(rays.size()) + " rays";
  if (!has_rows && !(rows.offsets.empty() && rows.hits.empty()))
    error = "all_hits left rows on a rank other than the root";
  for (std::size_t k = 0; k < rays.size() && error.empty(); ++k) {
    const std::vector<bd::IdHit>& row = want[k];
    const bd::IdHit first = row.empty() ? bd::IdHit{} : row.front();
    if (!(closest[k] == first))
      error = "ray " + std::to_string(k) + ": closest_hits gives " + hit_text(closest[k]) +
              ", brute force " + hit_text(first);
    else if (any[k] != (row.empty() ? 0 : 1))
      error = "ray " + std::to_string(k) + ": any_hits gives " + std::to_string(any[k]);
    else if (has_rows) {
      const std::vector<bd::IdHit> got(
          rows.hits.begin() + static_cast<std::ptrdiff_t>(rows.offsets[k]),
          rows.hits.begin() + static_cast<std::ptrdiff_t>(rows.offsets[k + 1]));
      if (got != row) {
        std::size_t j = 0;
        while (j < got.size() && j < row.size() && got[j] == row[j]) ++j;
        error = "ray " + std::to_string(k) + ": all_hits gives " + std::to_string(got.size()) +
                " hits, brute force " + std::to_string(row.size()) + "; first difference at " +
                std::to_string(j) + ": " + (j < got.size() ? hit_text(got[j]) : "end") +
                " against " + (j < row.size() ? hit_text(row[j]) : "end");
      }
    }
  }
  bd::agree(MPI_COMM_WORLD,
            error.empty() ? "" : where + ", rank " + std::to_string(rank_) + ": " + error);
  for (std::size_t k = 0; k < rays.size(); ++k) {
    counts.hits += want[k].size();
    if (want[k].size() > 1 && want[k][0].t == want[k][1].t) ++counts.ties;
    for (std::size_t i = 0; i < w.shapes.size(); ++i) {
      double t = 0;
      if (!broadphase::ray_sees(rays[k].mask, w.filters[i]) &&
          broadphase::ray_hit(rays[k], w.shapes[i], t))
        ++counts.masked;
    }
  }
}

// Moves the world one frame (reflecting in the box; on every sixth frame
// a few jumps across it, which make a tracker rebuild: a skin of 3 lasts
// the other frames) and redraws a few filters, static objects' included.
void step(World& w, Kind kind, int frame, std::mt19937_64& rng) {
  std::uniform_int_distribution<int> pct(0, 99);
  std::uniform_real_distribution<double> pos(0, kWorld);
  for (std::size_t i = 0; i < w.shapes.size(); ++i) {
    Vec3& c = w.shapes[i].center;
    Vec3& v = w.velocity[i];
    if (v.x != 0 || v.y != 0 || v.z != 0) {
      if (frame % 6 == 0 && pct(rng) < 2) {
        c = {pos(rng), pos(rng), pos(rng)};
      } else {
        for (int a = 0; a < 3; ++a) {
          c[a] += v[a];
          if (c[a] < -30 || c[a] > kWorld + 30) v[a] = -v[a];
        }
      }
    }
    if (pct(rng) < 5) w.filters[i] = draw_filter(kind, rng);
  }
}

std::vector<bd::IdPair> oracle(const World& w) {
  std::vector<bd::IdPair> out;
  const std::size_t n = w.shapes.size();
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      if (broadphase::filters_pass(w.filters[i], w.filters[j]) &&
          broadphase::overlaps(w.shapes[i], w.shapes[j]))
        out.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
  return out;
}

bool less(const bd::IdPair& p, const bd::IdPair& q) { return p.a != q.a ? p.a < q.a : p.b < q.b; }

std::string text(const std::vector<bd::IdPair>& v, std::size_t most) {
  std::string s;
  for (std::size_t k = 0; k < v.size() && k < most; ++k)
    s += " " + std::to_string(v[k].a) + "-" + std::to_string(v[k].b);
  if (v.size() > most) s += " ...";
  return s;
}

// Pairs of a run as brute force finds them, and the overlapping pairs
// that the filters rule out (so that a run shows they matter).
struct Counts {
  std::uint64_t pairs = 0, ruled_out = 0;
};

// Gathers every rank's pairs on rank 0 and compares them with the oracle;
// the verdict is agreed (MpiError on every rank when they differ).
void compare(const std::vector<bd::IdPair>& mine, const World& w, const std::string& where,
             Counts& counts_so_far) {
  const int bytes = static_cast<int>(mine.size() * sizeof(bd::IdPair));
  std::vector<int> counts(static_cast<std::size_t>(size_)), displs(counts.size());
  MPI_Gather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  int total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = total;
    total += counts[r];
  }
  std::vector<bd::IdPair> all(rank_ == 0 ? static_cast<std::size_t>(total) / sizeof(bd::IdPair)
                                         : 0);
  MPI_Gatherv(mine.data(), bytes, MPI_BYTE, all.data(), counts.data(), displs.data(), MPI_BYTE, 0,
              MPI_COMM_WORLD);
  std::string error;
  if (rank_ == 0) {
    std::vector<bd::IdPair> want = oracle(w);
    counts_so_far.pairs += want.size();
    for (std::size_t i = 0; i < w.shapes.size(); ++i)
      for (std::size_t j = i + 1; j < w.shapes.size(); ++j)
        if (!broadphase::filters_pass(w.filters[i], w.filters[j]) &&
            broadphase::overlaps(w.shapes[i], w.shapes[j]))
          ++counts_so_far.ruled_out;
    std::sort(all.begin(), all.end(), less);
    std::vector<bd::IdPair> missing, extra;
    std::set_difference(want.begin(), want.end(), all.begin(), all.end(),
                        std::back_inserter(missing), less);
    std::set_difference(all.begin(), all.end(), want.begin(), want.end(), std::back_inserter(extra),
                        less);
    if (!missing.empty() || !extra.empty() || all.size() != want.size())
      error = where + ": " + std::to_string(all.size()) + " pairs reported, " +
              std::to_string(want.size()) +
              " by brute force with the filters; missing:" + text(missing, 6) +
              "; extra or repeated:" + text(extra, 6);
  }
  bd::agree(MPI_COMM_WORLD, error);
}

enum class Entry { shapes_grid, objects_bisect, structure, tracker };
const char* name(Entry e) {
  switch (e) {
    case Entry::shapes_grid:
      return "Domain over shapes (grid)";
    case Entry::objects_bisect:
      return "Domain over Objects (bisection)";
    case Entry::structure:
      return "Domain with grid-hashed (grid)";
    default:
      return "PairTracker, skin 3 (grid)";
  }
}

std::string where_run(std::uint64_t seed, Kind kind, Entry entry) {
  return "seed " + std::to_string(seed) + ", " + name(kind) + ", " + name(entry);
}

// One world through one entry point for `frames` frames.
void run(std::uint64_t seed, Kind kind, Entry entry, std::size_t n, int frames) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + static_cast<std::uint64_t>(kind) * 7 +
                      static_cast<std::uint64_t>(entry));
  World w = make_world(kind, n, rng);
  bd::Options options;
  // Ghosts to at most two ranks each: the large objects go to the shared
  // list on 3 and 4 ranks, whose filters travel on their own path.
  options.max_ghost_ranks = 2;
  if (entry == Entry::objects_bisect) options.decomposition = bd::Decomposition::bisection;
  if (entry == Entry::structure) {
    options.algo = "grid-hashed";
    options.ray_algo = "grid-hashed";
  }
  bd::Domain domain(MPI_COMM_WORLD, {{0, 0, 0}, {kWorld, kWorld, kWorld}}, options);
  bd::PairTracker tracker(domain, 3.0);
  std::vector<std::uint32_t> ids, groups, masks;
  std::vector<Shape> shapes;
  std::vector<double> xyz, half;
  std::vector<std::uint8_t> kinds;
  std::vector<bd::IdPair> pairs;
  Counts counts;
  RayCounts ray_counts;
  std::mt19937_64 ray_rng(seed * 31 + static_cast<std::uint64_t>(kind) * 5 +
                          static_cast<std::uint64_t>(entry));
  for (int frame = 0; frame < frames; ++frame) {
    if (frame > 0) step(w, kind, frame, rng);
    if (entry == Entry::objects_bisect && frame % 4 == 0) {
      std::vector<Shape> owned;
      for (std::size_t i = 0; i < n; ++i)
        if (domain.partition().owner(w.shapes[i].center) == rank_) owned.push_back(w.shapes[i]);
      domain.balance(owned);
    }
    ids.clear();
    groups.clear();
    masks.clear();
    shapes.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const bool mine = entry == Entry::tracker
                            ? static_cast<int>(i % static_cast<std::size_t>(size_)) == rank_
                            : domain.partition().owner(w.shapes[i].center) == rank_;
      if (!mine) continue;
      ids.push_back(static_cast<std::uint32_t>(i));
      shapes.push_back(w.shapes[i]);
      groups.push_back(w.filters[i].group);
      masks.push_back(w.filters[i].mask);
    }
    pairs.clear();
    broadphase::Objects objects;
    if (entry == Entry::shapes_grid || entry == Entry::structure) {
      domain.find_pairs(ids, shapes, groups, masks, pairs);
      objects = bd::shapes_view(shapes.data(), shapes.size(), sizeof(Shape));
      objects.groups = groups;
      objects.masks = masks;
    } else {
      // Struct-of-arrays columns with a kind byte, as a particle code keeps
      // them.
      const std::size_t m = shapes.size();
      xyz.resize(3 * m);
      half.resize(3 * m);
      kinds.resize(m);
      for (std::size_t k = 0; k < m; ++k)
        for (int a = 0; a < 3; ++a) {
          xyz[3 * k + static_cast<std::size_t>(a)] = shapes[k].center[a];
          half[3 * k + static_cast<std::size_t>(a)] = shapes[k].half[a];
          kinds[k] = shapes[k].is_sphere() ? 0 : 1;
        }
      broadphase::Objects view = broadphase::Objects::boxes(xyz.data(), half.data(), m);
      view.radius = view.half_x;
      view.kind = kinds.data();
      view.groups = groups;
      view.masks = masks;
      if (entry == Entry::tracker)
        tracker.find_pairs(ids, view, pairs);
      else
        domain.find_pairs(ids, view, pairs);
      objects = view;
    }
    const std::string where = "seed " + std::to_string(seed) + ", " + name(kind) + ", " +
                              name(entry) + ", " + std::to_string(size_) + " ranks, frame " +
                              std::to_string(frame);
    compare(pairs, w, where, counts);
    check_rays(domain, ids, objects, w, kind, frame, ray_rng, where + ", rays", ray_counts);
  }
  if (rank_ == 0)
    std::printf(
        "  %s, %s: %llu pairs, %llu overlapping pairs ruled out by the filters; "
        "%llu ray hits, %llu closest hits tied in t, %llu hits ruled out by masks\n",
        name(kind), name(entry), static_cast<unsigned long long>(counts.pairs),
        static_cast<unsigned long long>(counts.ruled_out),
        static_cast<unsigned long long>(ray_counts.hits),
        static_cast<unsigned long long>(ray_counts.ties),
        static_cast<unsigned long long>(ray_counts.masked));
  // A run whose rays hit nothing, tie nowhere or meet no mask would test
  // little: the worlds are drawn so that each happens.
  bd::agree(MPI_COMM_WORLD, ray_counts.hits == 0 || ray_counts.ties == 0 || ray_counts.masked == 0
                                ? where_run(seed, kind, entry) +
                                      ": the rays met no hit, no tie "
                                      "or no mask"
                                : "");
  if (entry != Entry::tracker) return;
  // The frames between rebuilds are the ones where a changed filter must
  // travel along the kept lists: there must be some.
  bd::agree(MPI_COMM_WORLD, static_cast<int>(tracker.rebuilds()) * 2 > frames
                                ? std::string(name(kind)) + ": the tracker rebuilt " +
                                      std::to_string(tracker.rebuilds()) + " times in " +
                                      std::to_string(frames) + " frames"
                                : "");
  if (rank_ == 0)
    std::printf("  %s: the tracker rebuilt %llu times in %d frames\n", name(kind),
                static_cast<unsigned long long>(tracker.rebuilds()), frames);
}

// Columns that do not fit the objects are refused on every rank alike.
void bad_columns() {
  bd::Domain domain(MPI_COMM_WORLD, {{0, 0, 0}, {kWorld, kWorld, kWorld}});
  const std::vector<std::uint32_t> ids{static_cast<std::uint32_t>(rank_)};
  const std::vector<Shape> shapes{Shape::sphere({1, 1, 1}, 1)};
  const std::vector<std::uint32_t> groups{1}, none;
  std::vector<bd::IdPair> pairs;
  std::string error;
  try {
    // The last rank alone gives groups without masks.
    domain.find_pairs(ids, shapes, groups, rank_ == size_ - 1 ? none : groups, pairs);
    error = "columns of different lengths were accepted";
  } catch (const bd::MpiError& e) {
    if (std::string(e.what()).find("rank " + std::to_string(size_ - 1)) == std::string::npos)
      error = std::string("the refusal does not name the rank: ") + e.what();
  }
  bd::agree(MPI_COMM_WORLD, error);
}

// Bad rays, batches that differ between ranks and results of the wrong
// length: MpiError on every rank with the same message, naming the ray or
// the rank, and no rank left waiting (the test's timeout would show it).
void bad_rays() {
  bd::Domain domain(MPI_COMM_WORLD, {{0, 0, 0}, {kWorld, kWorld, kWorld}});
  const std::vector<std::uint32_t> ids{static_cast<std::uint32_t>(rank_)};
  const std::vector<Shape> shapes{Shape::sphere({10.0 * rank_, 1, 1}, 1)};
  const broadphase::Objects objects = bd::shapes_view(shapes.data(), 1, sizeof(Shape));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Ray good{{-5, 1, 1}, {1, 0, 0}};
  struct Case {
    const char* what;
    std::vector<Ray> rays;
    std::string pattern;
    std::size_t results;  // closest_hits' span on the last rank
  };
  const std::vector<Case> cases{
      {"a NaN origin", {good, good, Ray{{nan, 0, 0}, {1, 0, 0}}}, "invalid ray 2: origin", 3},
      {"an infinite direction", {Ray{{0, 0, 0}, {inf, 0, 0}}}, "invalid ray 0: direction", 1},
      {"a negative tmax", {good, Ray{{0, 0, 0}, {1, 0, 0}, -1}}, "invalid ray 1: tmax", 2},
      {"a NaN tmax", {Ray{{0, 0, 0}, {1, 0, 0}, nan}}, "invalid ray 0: tmax is NaN", 1},
      {"a batch that differs", {good, good}, "different batches", 2},
      {"a result span too short",
       {good, good},
       "rank " + std::to_string(size_ - 1) + ": 1 results",
       1},
  };
  for (const Case& c : cases) {
    std::vector<Ray> rays = c.rays;
    if (c.pattern == "different batches" && rank_ == size_ - 1) rays[1].tmax = 7;
    // One process has no other rank to differ from: expect success there.
    const bool fails = !(c.pattern == "different batches" && size_ == 1);
    std::vector<bd::IdHit> closest(rank_ == size_ - 1 ? c.results : rays.size());
    std::vector<std::uint8_t> any(rays.size());
    bd::IdHitRows rows;
    for (int call = 0; call < 3; ++call) {
      if (call > 0 && c.pattern.rfind("rank ", 0) == 0) break;  // closest_hits' span only
      std::string error, message;
      try {
        if (call == 0) domain.closest_hits(ids, objects, rays, closest);
        if (call == 1) domain.any_hits(ids, objects, rays, any);
        if (call == 2) domain.all_hits(ids, objects, rays, rows, 0);
        if (fails) error = std::string(c.what) + " was accepted";
      } catch (const bd::MpiError& e) {
        message = e.what();
        if (!fails || message.find(c.pattern) == std::string::npos)
          error = std::string(c.what) + ": unexpected message: " + message;
      }
      bd::agree(MPI_COMM_WORLD, error);
      // The same message on every rank.
      unsigned long long h = std::hash<std::string>{}(message), lo = h, hi = h;
      MPI_Allreduce(&h, &lo, 1, MPI_UNSIGNED_LONG_LONG, MPI_MIN, MPI_COMM_WORLD);
      MPI_Allreduce(&h, &hi, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
      bd::agree(MPI_COMM_WORLD,
                lo != hi ? std::string(c.what) + ": the ranks' messages differ" : "");
    }
  }
  {
    // An id given twice on the last rank: refused there, on every rank.
    const bool last = rank_ == size_ - 1;
    const std::vector<std::uint32_t> twice =
        last ? std::vector<std::uint32_t>{ids[0], ids[0]} : ids;
    const std::vector<Shape> two(twice.size(), shapes[0]);
    const std::vector<Ray> rays{good};
    std::vector<bd::IdHit> closest(1);
    std::string error = "an id given twice was accepted";
    try {
      domain.closest_hits(twice, bd::shapes_view(two.data(), two.size(), sizeof(Shape)), rays,
                          closest);
    } catch (const bd::MpiError& e) {
      const std::string m = e.what();
      error = m.find("rank " + std::to_string(size_ - 1) + ": id " + std::to_string(size_ - 1) +
                     " is given twice") == std::string::npos
                  ? "an id given twice: unexpected message: " + m
                  : "";
    }
    bd::agree(MPI_COMM_WORLD, error);
  }
  if (rank_ == 0) std::printf("bad rays: refused on every rank alike\n");
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  std::uint64_t seed = 1;
  int seeds = 2, frames = 12;
  std::size_t n = 400;
  for (int a = 1; a + 1 < argc; a += 2) {
    const std::string k = argv[a];
    const char* v = argv[a + 1];
    if (k == "--seed") seed = std::strtoull(v, nullptr, 10);
    if (k == "--seeds") seeds = std::atoi(v);
    if (k == "--frames") frames = std::atoi(v);
    if (k == "--objects") n = std::strtoull(v, nullptr, 10);
  }
  int status = 0;
  try {
    bad_columns();
    bad_rays();
    for (std::uint64_t s = seed; s < seed + static_cast<std::uint64_t>(seeds); ++s) {
      if (rank_ == 0)
        std::printf("seed %llu: %zu objects, %d frames, %d ranks\n",
                    static_cast<unsigned long long>(s), n, frames, size_);
      for (Kind kind : {Kind::random_bits, Kind::layers4, Kind::layers16})
        for (Entry entry :
             {Entry::shapes_grid, Entry::objects_bisect, Entry::structure, Entry::tracker})
          run(s, kind, entry, n, frames);
    }
    if (rank_ == 0) std::printf("ok\n");
  } catch (const bd::MpiError& e) {
    if (rank_ == 0) std::fprintf(stderr, "FAILED: %s\n", e.what());
    status = 1;
  }
  MPI_Finalize();
  return status;
}
