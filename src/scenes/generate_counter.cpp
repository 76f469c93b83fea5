// Counter-based generation: one short splitmix64 stream per object, seeded
// by the scene's seed and the object's index.
#include <broadphase/scenes/generate.hpp>
#include <cmath>
#include <stdexcept>
#include <string>

namespace broadphase {

bool counter_supported(Distribution d) {
  switch (d) {
    case Distribution::even:
    case Distribution::uneven:
    case Distribution::scaled_even:
    case Distribution::scaled_uneven:
    case Distribution::decades:
    case Distribution::all_moving:
    case Distribution::flat:
    case Distribution::outside:
      return true;
    default:
      return false;
  }
}

double counter_world(Distribution d, std::uint64_t n) {
  const bool scaled = d == Distribution::scaled_even || d == Distribution::scaled_uneven;
  return scaled && n > 0 ? 1000.0 * std::cbrt(static_cast<double>(n) / 6400.0) : 1000.0;
}

void generate_counter_range(Distribution d, std::uint64_t n, std::uint64_t seed,
                            std::uint64_t begin, std::uint64_t end, std::vector<Shape>& shapes,
                            std::vector<Vec3>& velocity) {
  if (!counter_supported(d))
    throw std::invalid_argument(std::string("counter generation does not support '") +
                                std::string(to_string(d)) +
                                "' (even, uneven, scaled-even, scaled-uneven, decades, "
                                "all-moving, flat, outside)");
  if (begin > end || end > n)
    throw std::invalid_argument("counter generation: range [" + std::to_string(begin) + ", " +
                                std::to_string(end) + ") is not within " + std::to_string(n) +
                                " objects");
  const double L = counter_world(d, n);
  const bool study = d == Distribution::even || d == Distribution::uneven ||
                     d == Distribution::scaled_even || d == Distribution::scaled_uneven;
  const bool uneven = d == Distribution::uneven || d == Distribution::scaled_uneven;
  const std::uint64_t base = splitmix64(seed);
  shapes.reserve(shapes.size() + (end - begin));
  velocity.reserve(velocity.size() + (end - begin));
  for (std::uint64_t i = begin; i < end; ++i) {
    // Every object draws the same numbers in the same order, whatever it
    // uses, so that a kind's choices never shift another object's stream.
    Rng rng(splitmix64(base + i));
    const bool moving = d == Distribution::all_moving || rng.uniform() < 0.2;
    const bool low = rng.uniform() < 0.8;
    Vec3 c{rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    const double u_radius = rng.uniform();
    const Vec3 dir = rng.direction();
    const double speed = rng.uniform(0.1, 2.0);
    const double u_out = rng.uniform(), u_side = rng.uniform(), u_big = rng.uniform();
    const auto axis = static_cast<int>(rng.below(3));
    double r = study ? 0.5 + 49.5 * u_radius : 0.5 + 4.5 * u_radius;
    if (uneven && low) c.y = c.y / 10;
    switch (d) {
      case Distribution::decades:
        r = std::pow(10.0, -3 + 5 * u_radius);
        break;
      case Distribution::flat:
        c.y = c.y / L;
        break;
      case Distribution::outside:
        if (u_out < 0.1) {
          c[axis] = u_side < 0.5 ? c[axis] - L : c[axis] + L;
          if (u_big < 0.002) r = L + L * u_radius;
        }
        break;
      default:
        break;
    }
    shapes.push_back(Shape::sphere(c, r));
    velocity.push_back(moving ? dir * speed : Vec3{});
  }
}

Scene generate_counter(Distribution d, std::uint64_t n, std::uint64_t seed) {
  Scene s;
  s.world = counter_world(d, n);
  generate_counter_range(d, n, seed, 0, n, s.objects, s.velocity);
  return s;
}

}  // namespace broadphase
