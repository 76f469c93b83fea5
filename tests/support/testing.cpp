#include "testing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <barrier>
#include <broadphase/naive.hpp>
#include <broadphase/scenes/replay.hpp>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <thread>

namespace broadphase::testing {

std::vector<ReferenceScene> reference_scenes() {
  std::vector<ReferenceScene> out;
  const std::filesystem::path dir = std::filesystem::path(BROADPHASE_TEST_DATA) / "scenes";
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".scene") continue;
    ReferenceScene r;
    r.name = entry.path().stem().string();
    r.scene_path = entry.path().string();
    std::ifstream in(std::filesystem::path(entry.path()).replace_extension(".expected"));
    std::uint64_t frame = 0, pairs = 0;
    std::string hash;
    while (in >> frame >> pairs >> hash) {
      FrameDigest d;
      d.pairs = pairs;
      d.hash = std::stoull(hash, nullptr, 16);
      r.expected.push_back(d);
    }
    out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  return out;
}

std::vector<std::string> library_structures() {
  std::vector<std::string> names;
  const Registry registry = Registry::library();
  for (const StructureInfo& e : registry.entries()) names.push_back(e.name);
  return names;
}

std::vector<std::string> structure_specs() {
  std::vector<std::string> specs = library_structures();
  specs.push_back("grid-verlet:threads=3,grain=1");
  // The default chooses how to find its movers' pairs from their motion:
  // each way on its own, whatever the scene.
  specs.push_back("grid-verlet:movers=lists");
  specs.push_back("grid-verlet:movers=dense,threads=2,grain=1");
  return specs;
}

std::vector<FrameDigest> replay(const std::string& spec, const Scene& scene, int frames,
                                bool validate_each_frame) {
  Config config;
  config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  config.expected_objects = scene.size();
  auto bp = make_structure(spec, config);
  Replay r(*bp, scene);
  std::vector<FrameDigest> out;
  for (int f = 0; f < frames; ++f) {
    out.push_back(r.next().digest);
    if (validate_each_frame) bp->validate();
  }
  return out;
}

std::string StructureParamName::identifier(std::string name) {
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
}

FrameDigest brute_force(const std::vector<Shape>& objects) {
  FrameDigest d;
  for (std::size_t i = 0; i < objects.size(); ++i)
    for (std::size_t j = i + 1; j < objects.size(); ++j)
      if (overlaps(objects[i], objects[j]))
        d.add(static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j));
  return d;
}

const char* to_string(World w) {
  switch (w) {
    case World::mixed:
      return "mixed";
    case World::touching:
      return "touching";
    case World::crowded:
      return "crowded";
    case World::far:
      return "far";
    case World::huge:
      return "huge";
    case World::extreme:
      return "extreme";
    case World::outside:
      return "outside";
    case World::many:
      return "many";
    case World::tiny:
      return "tiny";
    case World::shaped:
      return "shaped";
  }
  return "?";
}

const char* to_string(Filters f) {
  switch (f) {
    case Filters::none:
      return "none";
    case Filters::bits:
      return "bits";
    case Filters::layers4:
      return "layers4";
    case Filters::layers16:
      return "layers16";
  }
  return "?";
}

namespace {

// Draws shapes for one kind of world.
class ShapeSource {
 public:
  ShapeSource(World w, Rng& rng) : w_(w), rng_(rng) {}

  Shape draw() {
    switch (w_) {
      case World::mixed: {
        const Vec3 c{rng_.uniform(-100, 1100), rng_.uniform(-100, 1100), rng_.uniform(-100, 1100)};
        const double size = rng_.uniform() < 0.1 ? 0.0 : std::pow(10.0, rng_.uniform(-3, 2));
        return shaped(c, size);
      }
      case World::touching: {
        // Centres on a lattice of pitch 10 with radius or half side 5:
        // neighbours touch exactly, and many centres coincide.
        auto lattice = [&] { return 10.0 * static_cast<double>(rng_.below(8)); };
        const Vec3 c{lattice(), lattice(), lattice()};
        const double size = rng_.uniform() < 0.2 ? 0.0 : 5.0;
        return rng_.uniform() < 0.3 ? Shape::box(c, {size, size, size}) : Shape::sphere(c, size);
      }
      case World::crowded: {
        const Vec3 c{rng_.uniform(500, 501), rng_.uniform(500, 501), rng_.uniform(500, 501)};
        return shaped(c, rng_.uniform(0.001, 0.3));
      }
      case World::far: {
        const double base = 1e7;
        const Vec3 c{base + rng_.uniform(0, 1000), base + rng_.uniform(0, 1000),
                     -base + rng_.uniform(0, 1000)};
        return shaped(c, std::pow(10.0, rng_.uniform(-2, 2)));
      }
      case World::huge: {
        const Vec3 c{rng_.uniform(-500, 1500), rng_.uniform(-500, 1500), rng_.uniform(-500, 1500)};
        const double size =
            rng_.uniform() < 0.05 ? rng_.uniform(1000, 10000) : rng_.uniform(0.5, 50);
        return shaped(c, size);
      }
      case World::extreme: {
        // Mostly ordinary objects, with some whose coordinates or sizes are
        // so large that the contract's arithmetic overflows to infinity.
        auto coord = [&] {
          const double u = rng_.uniform();
          if (u < 0.7) return rng_.uniform(0, 1000);
          return (rng_.uniform() < 0.5 ? -1 : 1) * std::pow(10.0, rng_.uniform(3, 300));
        };
        const Vec3 c{coord(), coord(), coord()};
        const double u = rng_.uniform();
        const double size = u < 0.7 ? rng_.uniform(0, 50) : std::pow(10.0, rng_.uniform(0, 308));
        return shaped(c, size);
      }
      case World::outside: {
        // One object in ten larger than the world, the others far beside it.
        if (rng_.below(10) == 0)
          return shaped({rng_.uniform(0, 1000), rng_.uniform(0, 1000), rng_.uniform(0, 1000)},
                        rng_.uniform(1000, 3000));
        const double sign = rng_.below(2) == 0 ? 1 : -1;
        return shaped(
            {sign * rng_.uniform(1500, 5000), rng_.uniform(-5000, 5000), rng_.uniform(0, 1000)},
            rng_.uniform(1, 400));
      }
      case World::many:
        return shaped({rng_.uniform(0, 1000), rng_.uniform(0, 1000), rng_.uniform(0, 1000)},
                      rng_.uniform(1, 40));
      case World::tiny: {
        // Objects within 1e-150 of the origin, down to subnormal numbers:
        // the squares of their distances underflow to zero, where the
        // contract's predicate holds for objects far apart for their size.
        auto tiny = [&] { return std::pow(10.0, rng_.uniform(-323, -150)); };
        auto coord = [&] { return (rng_.uniform() < 0.5 ? -1 : 1) * tiny(); };
        const Vec3 c{coord(), coord(), coord()};
        return shaped(c, rng_.uniform() < 0.1 ? 0.0 : tiny());
      }
      case World::shaped: {
        // The shaped worlds of `gen` (shapes-uneven, shapes-decades), more
        // crowded: 80% of the centres in the lowest tenth of a cube of side
        // 300, sizes over four decades; one
        // object in five on a lattice of pitch 8 with dyadic half sides, so
        // that faces and ends touch exactly.
        if (rng_.below(5) == 0) {
          auto lattice = [&] { return 8.0 * static_cast<double>(rng_.below(6)); };
          const double s = 4.0 * static_cast<double>(1 + rng_.below(4));
          return elongated({lattice(), lattice(), lattice()}, s, s / 16);
        }
        const Vec3 c{rng_.uniform(0, 300),
                     rng_.uniform() < 0.8 ? rng_.uniform(0, 30) : rng_.uniform(0, 300),
                     rng_.uniform(0, 300)};
        const double s = std::pow(10.0, rng_.uniform(-2, 2));
        return elongated(c, s, s / std::pow(10.0, rng_.uniform(1, 2)));
      }
    }
    return {};
  }

  // A small move of `s` (or, sometimes, a jump anywhere, or a resize,
  // unless only small moves are wanted).
  Shape moved(Shape s, bool small_only) {
    const double u = small_only ? 1.0 : rng_.uniform();
    if (u < 0.15) return draw();
    if (u < 0.25) {
      const double k = rng_.uniform(0.25, 4);
      s.half = s.half * k;
      return s;
    }
    const double step = w_ == World::tiny ? std::max(s.max_half(), std::fabs(s.center.x))
                                          : std::max(1.0, s.max_half());
    for (int a = 0; a < 3; ++a) s.center[a] += rng_.uniform(-step, step);
    return s;
  }

 private:
  Shape shaped(Vec3 c, double size) {
    if (rng_.uniform() < 0.3)
      return Shape::box(c, {size * rng_.uniform(0.1, 1), size * rng_.uniform(0.1, 1),
                            size * rng_.uniform(0.1, 1)});
    return Shape::sphere(c, size);
  }
  // A sphere of radius `s`, or a box whose largest half side is `s`: a pole
  // (the two other sides `thin`), a slab (one side `thin`, or 0 one time in
  // four), three independent half sides up to `s`, or a cube.
  Shape elongated(Vec3 c, double s, double thin) {
    const int axis = static_cast<int>(rng_.below(3));
    Vec3 h{s, s, s};
    switch (rng_.below(5)) {
      case 0:
        return Shape::sphere(c, s);
      case 1:
        h = {thin, thin, thin};
        h[axis] = s;
        break;
      case 2:
        h[axis] = rng_.below(4) == 0 ? 0.0 : thin;
        break;
      case 3:
        h = {s * rng_.uniform(), s * rng_.uniform(), s * rng_.uniform()};
        break;
      default:
        break;
    }
    return Shape::box(c, h);
  }
  World w_;
  Rng& rng_;
};

struct Live {
  Handle s, n;  // in the structure under test, in the oracle
  std::uint64_t id;
};

// Draws filters for a differential run, and the pair filters it installs.
class FilterSource {
 public:
  FilterSource(Filters f, Rng& rng) : f_(f), rng_(rng) {}

  Filter draw() {
    switch (f_) {
      case Filters::none:
        return {};
      case Filters::bits: {
        // Low bits decide; a group of 0 (pairs with nothing) and the
        // default now and then.
        if (rng_.below(8) == 0) return {};
        const auto group = static_cast<std::uint32_t>(rng_.below(16));
        const auto mask = static_cast<std::uint32_t>(rng_.next());
        return {group, mask};
      }
      case Filters::layers4:
      case Filters::layers16: {
        const std::uint32_t n = f_ == Filters::layers4 ? 4 : 16;
        const auto layer = static_cast<std::uint32_t>(rng_.below(n));
        const std::uint32_t mask =
            (1u << layer) | (1u << ((layer + 1) % n)) | (1u << ((layer + n - 1) % n));
        return {1u << layer, mask};
      }
    }
    return {};
  }

  // A symmetric pair filter over user ids: about a third of the pairs fail.
  static bool pair_passes(std::uint64_t salt, std::uint64_t a, std::uint64_t b) {
    const std::uint64_t lo = std::min(a, b), hi = std::max(a, b);
    return splitmix64(salt ^ (lo * 0x9E3779B97F4A7C15ull) ^ (hi << 32 | hi >> 32)) % 3 != 0;
  }

 private:
  Filters f_;
  Rng& rng_;
};

std::vector<std::uint64_t> ids_of_query(const AnyBroadPhase& bp, const Shape& q) {
  std::vector<std::uint64_t> ids;
  bp.query(q, [&](Handle h) {
    ids.push_back(bp.user_data(h));
    return true;
  });
  std::sort(ids.begin(), ids.end());
  return ids;
}

std::vector<std::pair<std::uint64_t, std::uint64_t>> ids_of_pairs(const AnyBroadPhase& bp) {
  std::vector<HandlePair> pairs;
  bp.find_pairs(pairs);
  std::vector<std::pair<std::uint64_t, std::uint64_t>> ids;
  for (const HandlePair& p : pairs) {
    std::uint64_t a = bp.user_data(p.a), b = bp.user_data(p.b);
    ids.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

template <class T>
std::string describe_difference(const std::vector<T>& got, const std::vector<T>& want) {
  std::ostringstream out;
  out << "got " << got.size() << ", want " << want.size();
  if (std::adjacent_find(got.begin(), got.end()) != got.end()) out << " (got has duplicates)";
  return out.str();
}

}  // namespace

std::string differential_run(const Factory& make, const std::string& name, World world,
                             std::uint64_t seed, int steps, const DifferentialOptions& options) {
  const std::string who =
      name + " world=" + to_string(world) + " seed=" + std::to_string(seed) +
      (options.filters == Filters::none ? std::string()
                                        : std::string(" filters=") + to_string(options.filters)) +
      ": ";
  Rng rng(seed);
  ShapeSource source(world, rng);
  std::unique_ptr<AnyBroadPhase> bp;
  try {
    bp = make(options.config);
  } catch (const std::exception& e) {
    return who + "cannot make it: " + e.what();
  }
  Naive oracle;
  std::vector<Live> live;
  // The filters as the harness keeps them, by user id, and the salt of the
  // pair filter (0: none installed): the oracle gets no filters, so that
  // every structure, naive included, is checked against this record.
  FilterSource filter_source(options.filters, rng);
  std::vector<Filter> filter_of;
  std::uint64_t pair_salt = 0;
  auto want_pairs = [&] {
    std::vector<std::pair<std::uint64_t, std::uint64_t>> want;
    oracle.for_each_pair([&](Handle a, Handle b) {
      std::uint64_t x = oracle.user_data(a), y = oracle.user_data(b);
      if (!filters_pass(filter_of[x], filter_of[y])) return;
      if (pair_salt != 0 && !FilterSource::pair_passes(pair_salt, x, y)) return;
      want.emplace_back(std::min(x, y), std::max(x, y));
    });
    std::sort(want.begin(), want.end());
    return want;
  };
  std::uint64_t next_id = 0;
  Handle stale;  // the last handle removed, for bad moves
  const std::size_t target =
      options.max_objects > 0
          ? options.max_objects
          : (world == World::crowded ? 1500 : (world == World::many ? 2600 : 300));

  for (int step = 0; step < steps; ++step) {
    const std::string where =
        " at step " + std::to_string(step) + " (seed " + std::to_string(seed) + ")";
    const double u = rng.uniform();
    const double insert_p = live.size() < target ? 0.45 : 0.2;
    std::string op;
    try {
      if (options.filters != Filters::none && !live.empty() && rng.uniform() < 0.1) {
        // A filter change (or a pair filter installed or removed), then the
        // pairs at once: what the change dropped or brought must show.
        if (rng.uniform() < 0.2) {
          op = "set_pair_filter";
          pair_salt = pair_salt == 0 || rng.uniform() < 0.3 ? rng.next() | 1 : 0;
          PairFilter pf;
          if (pair_salt != 0) {
            const AnyBroadPhase* b = bp.get();
            pf = [b, salt = pair_salt](Handle x, Handle y) {
              return FilterSource::pair_passes(salt, b->user_data(x), b->user_data(y));
            };
          }
          bp->set_pair_filter(std::move(pf));
        } else {
          // One change, or a few in a row (a cache dropped by the first
          // must not be rebuilt before the others).
          op = "set_filter";
          const std::uint64_t changes = rng.uniform() < 0.7 ? 1 : 2 + rng.below(4);
          for (std::uint64_t c = 0; c < changes; ++c) {
            const Live& o = live[rng.below(live.size())];
            const Filter f = filter_source.draw();
            bp->set_filter(o.s, f);
            filter_of[o.id] = f;
            if (!(bp->filter(o.s) == f))
              return who + "filter() does not return the filter set" + where;
          }
        }
        // Settled or not: a cache the change invalidated is read either way.
        if (rng.uniform() < 0.5) bp->settle();
        bp->validate();
        const auto got = ids_of_pairs(*bp);
        const auto want = want_pairs();
        if (got != want)
          return who + "after " + op +
                 ", pairs differ from brute force: " + describe_difference(got, want) + where;
        continue;
      }
      if (u < insert_p || live.empty()) {
        op = "insert";
        const Shape s = source.draw();
        const Motion m = rng.uniform() < 0.5 ? Motion::dynamic : Motion::fixed;
        const Filter f = filter_source.draw();
        live.push_back({bp->insert(s, next_id, m, f), oracle.insert(s, next_id, m), next_id});
        filter_of.push_back(f);
        ++next_id;
      } else if (u < insert_p + 0.12) {
        op = "remove";
        const std::size_t k = rng.below(live.size());
        const Handle gone = live[k].s;
        stale = gone;
        bp->remove(gone);
        oracle.remove(live[k].n);
        live[k] = live.back();
        live.pop_back();
        if (bp->contains(gone)) {
          return who + "a removed handle is still reported as contained" + where;
        }
        bool threw = false;
        try {
          bp->remove(gone);
        } catch (const InvalidHandle&) {
          threw = true;
        }
        if (!threw) {
          return who + "removing a stale handle did not throw InvalidHandle" + where;
        }
      } else if (u < insert_p + 0.40) {
        op = "update";
        // Either one update or a bulk batch.
        if (rng.uniform() < 0.7) {
          const Live& o = live[rng.below(live.size())];
          const Shape s = source.moved(oracle.shape(o.n), options.small_moves);
          bp->update(o.s, s);
          oracle.update(o.n, s);
        } else {
          // A bulk batch; sometimes naming a handle twice (the last move
          // wins), sometimes with one bad move at a random place (the whole
          // batch must then be refused and change nothing).
          std::vector<Move> batch;
          std::vector<std::size_t> picks;
          std::vector<std::ptrdiff_t> last(live.size(), -1);  // pick -> its last move
          const bool repeats = rng.uniform() < 0.2;
          const std::size_t k = 1 + rng.below(std::min<std::size_t>(live.size(), 64));
          for (std::size_t t = 0; t < k; ++t) {
            const std::size_t pick = rng.below(live.size());
            if (last[pick] >= 0 && !repeats) continue;
            const Shape base = last[pick] >= 0 ? batch[static_cast<std::size_t>(last[pick])].shape
                                               : oracle.shape(live[pick].n);
            last[pick] = static_cast<std::ptrdiff_t>(batch.size());
            batch.push_back({live[pick].s, source.moved(base, options.small_moves)});
            picks.push_back(pick);
          }
          const bool inject = rng.uniform() < 0.25;
          if (inject) {
            const std::size_t at = rng.below(batch.size() + 1);
            const double nan = std::numeric_limits<double>::quiet_NaN();
            Move bad = batch.empty() ? Move{live[0].s, {}} : batch[rng.below(batch.size())];
            switch (rng.below(stale.is_null() ? 3 : 4)) {
              case 0:
                bad.shape.center.y = nan;
                op = "bulk update with a NaN centre at " + std::to_string(at);
                break;
              case 1:
                bad.shape = Shape::sphere(bad.shape.center, -1);
                op = "bulk update with a negative radius at " + std::to_string(at);
                break;
              case 2:
                bad.shape.half.z = std::numeric_limits<double>::infinity();
                op = "bulk update with an infinite extent at " + std::to_string(at);
                break;
              default:
                bad.handle = stale;
                op = "bulk update with a stale handle at " + std::to_string(at);
                break;
            }
            batch.insert(batch.begin() + static_cast<std::ptrdiff_t>(at), bad);
            bool refused = false;
            try {
              bp->update(batch);
            } catch (const InvalidShape&) {
              refused = true;
            } catch (const InvalidHandle&) {
              refused = true;
            }
            if (!refused) {
              return who + op + " was not refused" + where;
            }
            bp->validate();
            const auto got = ids_of_pairs(*bp);
            const auto want = want_pairs();
            if (got != want) {
              return who + "after a refused " + op +
                     ", pairs differ from naive: " + describe_difference(got, want) + where;
            }
            for (const Live& o : live)
              if (!(bp->shape(o.s) == oracle.shape(o.n))) {
                return who + "a refused " + op + " changed object " + std::to_string(o.id) + where;
              }
          } else {
            bp->update(batch);
            for (std::size_t t = 0; t < batch.size(); ++t)
              oracle.update(live[picks[t]].n, batch[t].shape);
          }
        }
      } else if (u < insert_p + 0.52) {
        op = "query";
        const Shape q = rng.uniform() < 0.5 && !live.empty()
                            ? oracle.shape(live[rng.below(live.size())].n)
                            : source.draw();
        const auto got = ids_of_query(*bp, q);
        std::vector<std::uint64_t> want;
        oracle.query(q, [&](Handle h) { want.push_back(oracle.user_data(h)); });
        std::sort(want.begin(), want.end());
        if (got != want) {
          return who + "query differs from naive: " + describe_difference(got, want) + where;
        }
        // An early-stopping visitor must see exactly one hit when there are any.
        int seen = 0;
        const QueryCost c = bp->query(q, [&](Handle) {
          ++seen;
          return false;
        });
        if (seen != (want.empty() ? 0 : 1) || c.stopped != !want.empty()) {
          return who + "early stop not honoured (saw " + std::to_string(seen) + ")" + where;
        }
      } else {
        op = "all pairs";
        const auto got = ids_of_pairs(*bp);
        const auto want = want_pairs();
        if (got != want) {
          return who + "all pairs differ from naive: " + describe_difference(got, want) + where;
        }
        // The same pairs through the visitor, and an early stop after one.
        std::vector<std::pair<std::uint64_t, std::uint64_t>> visited;
        bp->for_each_pair([&](Handle a, Handle b) {
          const std::uint64_t x = bp->user_data(a), y = bp->user_data(b);
          visited.emplace_back(std::min(x, y), std::max(x, y));
          return true;
        });
        std::sort(visited.begin(), visited.end());
        if (visited != want)
          return who + "for_each_pair differs from naive: " + describe_difference(visited, want) +
                 where;
        int seen = 0;
        const QueryCost c = bp->for_each_pair([&](Handle, Handle) {
          ++seen;
          return false;
        });
        if (seen != (want.empty() ? 0 : 1) || c.stopped != !want.empty())
          return who + "for_each_pair ignored a stop (saw " + std::to_string(seen) + ")" + where;
      }
      if (step % 53 == 52) {  // now and then the commit step, which changes no answer
        op = "settle after " + op;
        bp->settle();
      }
      bp->validate();
      if (bp->size() != oracle.size()) {
        return who + "size " + std::to_string(bp->size()) + " != " + std::to_string(oracle.size()) +
               where;
      }
    } catch (const std::exception& e) {
      return who + op + " threw: " + e.what() + where;
    }
  }
  return {};
}

void differential(const std::string& spec, World world, std::uint64_t seed, int steps,
                  const Config& config, Filters filters) {
  DifferentialOptions options;
  options.config = config;
  options.filters = filters;
  const std::string failure = differential_run(
      [&](const Config& c) { return make_structure(spec, c); }, spec, world, seed, steps, options);
  if (!failure.empty()) ADD_FAILURE() << failure;
}

void const_calls_on_two_threads(const std::string& spec, const Scene& scene) {
  Config c;
  c.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
  auto bp = make_structure(spec, c);
  // Filled, then one frame's bulk update: structures on threads split it
  // and the pairs.
  std::vector<Move> moves;
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const bool moving = scene.is_moving(i);
    const Handle h = bp->insert(scene.objects[i], i, moving ? Motion::dynamic : Motion::fixed);
    if (moving) moves.push_back({h, scene.objects[i]});
  }
  bp->update(moves);
  using Pairs = std::vector<std::pair<std::uint64_t, std::uint64_t>>;
  using Hits = std::vector<std::vector<std::uint64_t>>;
  auto queries = [&] {
    Hits hits;
    for (std::size_t i = 0; i < scene.size(); i += 7)
      hits.push_back(ids_of_query(*bp, scene.objects[i]));
    return hits;
  };
  const Pairs want_pairs = ids_of_pairs(*bp);
  const Hits want_hits = queries();
  std::vector<Pairs> got_pairs(2);
  std::vector<Hits> got_hits(2);
  {
    // Both threads start each kind of call together, so that the calls
    // overlap.
    std::barrier sync(2);
    std::vector<std::jthread> threads;
    for (std::size_t t = 0; t < 2; ++t)
      threads.emplace_back([&, t] {
        sync.arrive_and_wait();
        for (int round = 0; round < 5; ++round) got_pairs[t] = ids_of_pairs(*bp);
        sync.arrive_and_wait();
        got_hits[t] = queries();
        sync.arrive_and_wait();
        bp->validate();
        EXPECT_GT(bp->memory_bytes(), 0u);
      });
  }
  for (std::size_t t = 0; t < 2; ++t) {
    EXPECT_EQ(got_pairs[t], want_pairs) << spec << ", thread " << t;
    EXPECT_EQ(got_hits[t], want_hits) << spec << ", thread " << t;
  }
}

}  // namespace broadphase::testing
