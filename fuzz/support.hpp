// What the fuzz targets share: the nasty values their shapes are drawn
// from, and a structure driven beside the naive oracle that aborts (a
// finding for libFuzzer) on the first answer that differs or the first
// invariant validate() reports broken.
#pragma once

#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace broadphase::fuzz {

/// Reports a finding: prints what differed and aborts.
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

/// Coordinates where arithmetic breaks: zero, subnormals, values that touch
/// exactly (centres 1 apart with radius 0.5 or 1), 1e7 (where floats lose
/// units), and the ends of the double range.
inline double nasty_coordinate(FuzzedDataProvider& in) {
  static constexpr double kDenorm = std::numeric_limits<double>::denorm_min();
  static constexpr double kMax = std::numeric_limits<double>::max();
  static constexpr double kValues[] = {0.0,     -0.0, kDenorm, -kDenorm, 2 * kDenorm, 1e-308, 0.5,
                                       1.0,     2.0,  -1.0,    3.0,      10.0,        1000.0, 1e7,
                                       1e7 + 1, -1e7, 1e300,   -1e300,   kMax,        -kMax,  1e308,
                                       4e307,   0.25, 0.125,   999.5,    5.0};
  static constexpr std::size_t kCount = sizeof kValues / sizeof kValues[0];
  const std::uint8_t b = in.ConsumeIntegral<std::uint8_t>();
  if (b < 2 * kCount) return kValues[b % kCount];
  // The rest: a small integer lattice, where centres coincide and touch.
  return static_cast<double>(static_cast<int>(b % 16) - 4);
}

/// Radii and half-extents from 0 through subnormals to 1e300.
inline double nasty_size(FuzzedDataProvider& in) {
  static constexpr double kValues[] = {0.0,   std::numeric_limits<double>::denorm_min(),
                                       0.5,   1.0,
                                       2.0,   5.0,
                                       1e7,   1e150,
                                       1e300, 1e-300,
                                       0.25,  3.0};
  return kValues[in.ConsumeIntegral<std::uint8_t>() % (sizeof kValues / sizeof kValues[0])];
}

/// A sphere or a box at nasty coordinates.
inline Shape nasty_shape(FuzzedDataProvider& in) {
  const bool box = in.ConsumeBool();
  const Vec3 c{nasty_coordinate(in), nasty_coordinate(in), nasty_coordinate(in)};
  if (box) return Shape::box(c, {nasty_size(in), nasty_size(in), nasty_size(in)});
  return Shape::sphere(c, nasty_size(in));
}

/// A shape that every structure must refuse with InvalidShape.
inline Shape bad_shape(FuzzedDataProvider& in) {
  Shape s = Shape::sphere({1, 2, 3}, 1);
  switch (in.ConsumeIntegral<std::uint8_t>() % 4) {
    case 0:
      s.center.x = std::numeric_limits<double>::quiet_NaN();
      break;
    case 1:
      s = Shape::sphere({0, 0, 0}, -1);
      break;
    case 2:
      s.center.z = std::numeric_limits<double>::infinity();
      break;
    default:
      s = Shape::box({0, 0, 0}, {1, std::numeric_limits<double>::infinity(), 1});
      break;
  }
  return s;
}

/// A structure under test and the naive oracle, holding the same objects
/// (user data: an id of the fuzz input's own), compared after every step.
class Twin {
 public:
  Twin(std::unique_ptr<AnyBroadPhase> s, std::string name)
      : s_(std::move(s)), name_(std::move(name)) {}

  std::size_t size() const { return live_.size(); }

  void insert(const Shape& shape) {
    const std::uint64_t id = next_id_++;
    const Motion m = id % 3 == 0 ? Motion::fixed : Motion::dynamic;
    live_.push_back({s_->insert(shape, id, m), oracle_.insert(shape, id, m), id});
    check("insert");
  }
  void remove(std::size_t k) {
    if (live_.empty()) return;
    k %= live_.size();
    const Handle gone = live_[k].s;
    s_->remove(gone);
    oracle_.remove(live_[k].n);
    live_[k] = live_.back();
    live_.pop_back();
    stale_ = gone;
    if (s_->contains(gone)) finding(name_ + ": a removed handle is still contained");
    check("remove");
  }
  void update(std::size_t k, const Shape& shape) {
    if (live_.empty()) return;
    k %= live_.size();
    s_->update(live_[k].s, shape);
    oracle_.update(live_[k].n, shape);
    check("update");
  }
  /// A bulk update of (object index, shape) moves; with `bad_at` <= moves,
  /// a bad move (`bad`, or a stale handle when `stale` and there is one)
  /// inserted there, which must make the whole batch change nothing.
  void bulk(const std::vector<std::pair<std::size_t, Shape>>& moves, std::size_t bad_at,
            const Shape& bad, bool stale) {
    if (live_.empty()) return;
    std::vector<Move> batch;
    for (const auto& [k, shape] : moves) batch.push_back({live_[k % live_.size()].s, shape});
    const bool inject = bad_at <= batch.size();
    if (inject) {
      Move m{live_[0].s, bad};
      if (stale && !stale_.is_null()) m = {stale_, Shape::sphere({0, 0, 0}, 1)};
      batch.insert(batch.begin() + static_cast<std::ptrdiff_t>(bad_at), m);
      bool refused = false;
      try {
        s_->update(batch);
      } catch (const InvalidShape&) {
        refused = true;
      } catch (const InvalidHandle&) {
        refused = true;
      }
      if (!refused) finding(name_ + ": a batch with a bad move was not refused");
      check("refused bulk update");
      return;
    }
    s_->update(batch);
    for (const auto& [k, shape] : moves) oracle_.update(live_[k % live_.size()].n, shape);
    check("bulk update");
  }
  void refused_single(const Shape& bad) {
    if (live_.empty()) return;
    bool refused = false;
    try {
      s_->update(live_[0].s, bad);
    } catch (const InvalidShape&) {
      refused = true;
    }
    if (!refused) finding(name_ + ": a bad shape was not refused by update");
    refused = false;
    try {
      s_->insert(bad, 0);
    } catch (const InvalidShape&) {
      refused = true;
    }
    if (!refused) finding(name_ + ": a bad shape was not refused by insert");
    check("refused single calls");
  }
  void query(const Shape& q) {
    std::vector<std::uint64_t> got, want;
    s_->query(q, [&](Handle h) {
      got.push_back(s_->user_data(h));
      return true;
    });
    oracle_.query(q, [&](Handle h) { want.push_back(oracle_.user_data(h)); });
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    if (got != want)
      finding(name_ + ": query gives " + std::to_string(got.size()) + " objects, naive " +
              std::to_string(want.size()));
  }
  void all_pairs() {
    std::vector<HandlePair> pairs;
    s_->find_pairs(pairs);
    std::vector<std::pair<std::uint64_t, std::uint64_t>> got, want, visited;
    for (const HandlePair& p : pairs)
      got.push_back(ordered(s_->user_data(p.a), s_->user_data(p.b)));
    s_->for_each_pair([&](Handle a, Handle b) {
      visited.push_back(ordered(s_->user_data(a), s_->user_data(b)));
      return true;
    });
    oracle_.for_each_pair([&](Handle a, Handle b) {
      want.push_back(ordered(oracle_.user_data(a), oracle_.user_data(b)));
    });
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    std::sort(visited.begin(), visited.end());
    if (got != want)
      finding(name_ + ": find_pairs gives " + std::to_string(got.size()) + " pairs, naive " +
              std::to_string(want.size()));
    if (visited != want)
      finding(name_ + ": for_each_pair gives " + std::to_string(visited.size()) + " pairs, naive " +
              std::to_string(want.size()));
  }

 private:
  struct Live {
    Handle s, n;
    std::uint64_t id;
  };
  static std::pair<std::uint64_t, std::uint64_t> ordered(std::uint64_t a, std::uint64_t b) {
    return {std::min(a, b), std::max(a, b)};
  }
  // After every mutation: the invariants, the size and every shape.
  void check(const char* after) {
    try {
      s_->validate();
    } catch (const std::exception& e) {
      finding(name_ + ": validate() after " + after + ": " + e.what());
    }
    if (s_->size() != oracle_.size()) finding(name_ + ": size differs after " + std::string(after));
    for (const Live& o : live_)
      if (!(s_->shape(o.s) == oracle_.shape(o.n)))
        finding(name_ + ": object " + std::to_string(o.id) + "'s shape differs after " + after);
  }

  std::unique_ptr<AnyBroadPhase> s_;
  std::string name_;
  Naive oracle_;
  std::vector<Live> live_;
  Handle stale_;
  std::uint64_t next_id_ = 0;
};

}  // namespace broadphase::fuzz
