// Replays of scenes built to break a broad phase's arithmetic, for every
// structure of the library against the naive oracle, frame by frame:
// coordinates near the ends of the double range, exact touching on cell
// boundaries, motion that leaves the world, identical and signed-zero
// centres. Each kind is drawn with several seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "testing.hpp"

namespace broadphase::testing {
namespace {

// The project's generator, with the draws these scenes use.
class Draw {
 public:
  explicit Draw(std::uint64_t seed) : rng_(seed) {}
  double uniform(double a, double b) { return rng_.uniform(a, b); }
  double log_uniform(double a, double b) { return std::exp(uniform(std::log(a), std::log(b))); }
  int below(int n) { return static_cast<int>(rng_.below(static_cast<std::uint64_t>(n))); }
  bool chance(int one_in) { return below(one_in) == 0; }

 private:
  Rng rng_;
};

struct Kind {
  const char* name;
  std::function<Scene(Draw&, int)> make;
};

void add(Scene& s, Draw& d, Vec3 c, double size, Vec3 v, bool box) {
  s.objects.push_back(box ? Shape::box(c, {size, size * d.uniform(0, 1), size * d.uniform(0, 1)})
                          : Shape::sphere(c, size));
  s.velocity.push_back(v);
}

const std::vector<Kind>& kinds() {
  static const std::vector<Kind> k = {
      {"sizes over eight decades, some outside, some fast",
       [](Draw& d, int n) {
         Scene s;
         s.world = d.log_uniform(1e-3, 1e6);
         const double L = s.world;
         for (int i = 0; i < n; ++i) {
           const Vec3 c{d.uniform(-0.2, 1.2) * L, d.uniform(-0.2, 1.2) * L,
                        d.uniform(-0.2, 1.2) * L};
           const double size = d.chance(20) ? 0 : d.log_uniform(1e-7, 0.5) * L;
           const double sp = d.chance(4) ? d.log_uniform(1e-6, 2) * L : 0;
           add(s, d, c, size, {d.uniform(-sp, sp), d.uniform(-sp, sp), d.uniform(-sp, sp)},
               d.chance(3));
         }
         return s;
       }},
      {"subnormal coordinates and sizes",
       [](Draw& d, int n) {
         Scene s;
         s.world = 1e-300;
         for (int i = 0; i < n; ++i) {
           const Vec3 c{d.uniform(-1, 2) * 1e-308, d.uniform(-1, 2) * 1e-308,
                        d.uniform(-1, 2) * 1e-308};
           const Vec3 v{d.chance(2) ? d.uniform(-1, 1) * 1e-309 : 0, 0, 0};
           add(s, d, c, d.log_uniform(1e-320, 1e-308), v, d.chance(3));
         }
         return s;
       }},
      {"tiny objects near the origin beside ordinary ones",
       [](Draw& d, int n) {
         Scene s;
         s.world = 10;
         for (int i = 0; i < n; ++i) {
           if (d.chance(2)) {
             auto tiny = [&] { return d.uniform(-1, 1) * std::pow(10.0, d.uniform(-320, -140)); };
             add(s, d, {tiny(), tiny(), tiny()}, std::pow(10.0, d.uniform(-323, -150)),
                 {d.chance(3) ? 1e-160 * d.uniform(-1, 1) : 0, 0, 0}, d.chance(4));
           } else {
             add(s, d, {d.uniform(-5, 5), d.uniform(-5, 5), d.uniform(-5, 5)},
                 d.log_uniform(1e-3, 2), {d.uniform(-1, 1), d.uniform(-1, 1), 0}, d.chance(4));
           }
         }
         return s;
       }},
      {"coordinates and sizes near the top of the double range",
       [](Draw& d, int n) {
         Scene s;
         s.world = 1e300;
         for (int i = 0; i < n; ++i) {
           const Vec3 c{d.uniform(-1, 1) * std::pow(10.0, d.uniform(0, 308)),
                        d.uniform(-1, 1) * std::pow(10.0, d.uniform(0, 308)),
                        d.uniform(-1, 1) * 1.7e308};
           const double size = d.chance(5) ? std::pow(10.0, d.uniform(150, 307))
                                           : std::pow(10.0, d.uniform(-5, 300));
           add(s, d, c, size, {d.chance(3) ? d.uniform(-1, 1) * 1e299 : 0, 0, 0}, d.chance(3));
         }
         return s;
       }},
      {"exact touching on power-of-two cell boundaries, flat boxes",
       [](Draw& d, int n) {
         Scene s;
         s.world = 1024;
         for (int i = 0; i < n; ++i) {
           const Vec3 c{64.0 * d.below(17), 64.0 * d.below(17), 32.0 * d.below(33)};
           const Vec3 v = d.chance(2) ? Vec3{32.0 * (d.below(5) - 2), 16.0 * (d.below(5) - 2), 0}
                                      : Vec3{0, 0, 0};
           if (d.chance(2))
             s.objects.push_back(Shape::box(c, {32.0 * d.below(3), 0, 16.0 * d.below(2)}));
           else
             s.objects.push_back(Shape::sphere(c, 32.0 * d.below(3)));
           s.velocity.push_back(v);
         }
         return s;
       }},
      {"velocities far beyond the world",
       [](Draw& d, int n) {
         Scene s;
         s.world = 100;
         for (int i = 0; i < n; ++i) {
           const double sp = d.chance(2) ? d.log_uniform(1, 1e4) : 0;
           add(s, d, {d.uniform(0, 100), d.uniform(0, 100), d.uniform(0, 100)},
               d.log_uniform(0.1, 20), {d.uniform(-sp, sp), d.uniform(-sp, sp), d.uniform(-sp, sp)},
               d.chance(3));
         }
         return s;
       }},
      {"signed zeros and identical centres",
       [](Draw& d, int n) {
         Scene s;
         s.world = 10;
         for (int i = 0; i < n; ++i) {
           const Vec3 c{d.chance(2) ? -0.0 : 0.0, d.chance(2) ? -0.0 : 0.0,
                        static_cast<double>(d.below(3))};
           add(s, d, c, d.chance(2) ? 0.0 : 0.5,
               {d.chance(3) ? (d.chance(2) ? 1.0 : -1.0) : 0, 0, 0}, d.chance(3));
         }
         return s;
       }},
  };
  return k;
}

class NastyScenes : public ::testing::TestWithParam<std::string> {};

TEST_P(NastyScenes, MatchNaiveOnEveryFrame) {
  constexpr int kFrames = 5;
  for (const Kind& kind : kinds()) {
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
      Draw d(seed * 1000 + static_cast<std::uint64_t>(&kind - kinds().data()));
      const Scene scene = kind.make(d, 40 + d.below(160));
      const std::vector<FrameDigest> want = replay("naive", scene, kFrames);
      const std::vector<FrameDigest> got = replay(GetParam(), scene, kFrames, true);
      ASSERT_EQ(got.size(), want.size());
      for (int f = 0; f < kFrames; ++f)
        ASSERT_EQ(got[static_cast<std::size_t>(f)], want[static_cast<std::size_t>(f)])
            << kind.name << ", seed " << seed << ", " << scene.size() << " objects, frame " << f;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(All, NastyScenes, ::testing::ValuesIn(structure_specs()),
                         StructureParamName{});

}  // namespace
}  // namespace broadphase::testing
