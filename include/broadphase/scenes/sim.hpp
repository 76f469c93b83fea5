/// \file lab/sim.hpp
/// A small rigid-sphere simulation on top of any broad phase: motion,
/// bounces off the world's walls and off each other, positional correction,
/// and three ways of finding contacts within a step (discrete, per-object
/// substeps, continuous). It measures the contacts a method misses against
/// the exact swept-sphere ground truth.
///
/// The model (docs/simulation.md has the formulas): objects move linearly
/// within a step; a moving object bounces off the six faces of the world
/// cube [0, L]^3 (y = 0 is the ground); two objects that touch exchange an
/// impulse along the line of their centres, masses proportional to r³,
/// restitution k; static objects (zero velocity in the scene) have infinite
/// mass and never move. A box is treated as its bounding sphere for the
/// response, the mass and the time of impact, but as a box against the walls
/// and for detection (the exact `overlaps()`).
///
/// Determinism: contacts are resolved in an order that depends only on the
/// object ids and times, never on the order a structure reports pairs in, so
/// every exact structure gives the same trajectories bit for bit.
#pragma once

#include <broadphase/geometry.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/structure.hpp>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

namespace broadphase {

/// How contacts are found within a step.
enum class Ccd : std::uint8_t {
  off,      ///< move everything, then test once at the end of the step
  substep,  ///< each object is tested at its own finer interval, by its speed/size
  swept,    ///< swept bounds in the broad phase, exact time of impact, earliest first
};

/// Parses "off", "substep" or "swept". Throws std::invalid_argument.
Ccd parse_ccd(std::string_view name);
/// The name `parse_ccd` accepts for `c`.
std::string_view to_string(Ccd c);

/// Simulation parameters. Every field has a sensible default.
struct SimConfig {
  double restitution = 1;  ///< k in [0, 1]: 1 elastic, 0 perfectly plastic
  double dt = 1;           ///< step length in frames (velocities are per frame)
  Ccd ccd = Ccd::off;
  /// substep: an object is tested after moving at most this fraction of its
  /// (bounding) radius.
  double substep_fraction = 0.5;
  /// substep: the most substeps any object gets in one step (a power of two).
  int max_substeps = 64;
  /// swept: at most this many events per step and moving object, so that a
  /// body squeezed between static objects cannot stall a step.
  int max_events_per_mover = 16;
  /// Computes the exact ground truth every step and counts missed contacts
  /// (costs a sweep over all swept bounds; not included in `seconds`).
  bool measure_missed = true;
};

/// What one step did and the state after it.
struct StepStats {
  std::uint64_t contacts = 0;       ///< impulses applied between two objects
  std::uint64_t wall_hits = 0;      ///< bounces off the world's faces
  std::uint64_t true_contacts = 0;  ///< ground truth: pairs that came into contact
  std::uint64_t missed = 0;         ///< true contacts the method never registered
  std::uint64_t tests = 0;          ///< exact predicate evaluations of the broad phase
  std::uint64_t evaluations = 0;    ///< broad-phase passes: 1, substep ticks, or events
  double kinetic_energy = 0;        ///< Σ ½ m |v|² after the step
  Vec3 momentum;                    ///< Σ m v after the step
  double max_penetration = 0;       ///< deepest overlap left after the step
  double seconds = 0;               ///< time of the step without the ground truth
};

/// Σ ½ m |v|² with m = R³ (R the bounding radius) over moving objects.
double kinetic_energy(const Scene& scene);
/// Σ m v with m = R³ over moving objects.
Vec3 momentum(const Scene& scene);

/// The velocities of two bodies after an impulse along the unit normal `n`
/// (pointing from a to b), restitution k; inverse masses `wa`, `wb` (0 is a
/// static body). Nothing changes when they separate along `n` or both are
/// static. Returns true when an impulse was applied. O(1).
bool collide(Vec3& va, Vec3& vb, double wa, double wb, const Vec3& n, double k);

/// A bounce off a plane with unit normal `n` pointing into the free side:
/// v = vp + vn becomes vp − k·vn when v moves into the plane. Returns true
/// when it bounced. O(1).
bool bounce(Vec3& v, const Vec3& n, double k);

/// A scene made to tunnel: small fast bullets (radius 0.5, 8 to 25 units per
/// frame, mostly along ±x) crossing three thin layers of small static
/// targets (radius 2, 20 apart) in a 200-unit world. A discrete step misses
/// most of their contacts. `flat`: everything in the plane z = 100 (one
/// target per layer and height), for pictures seen from the side.
/// Deterministic for a seed.
Scene make_tunnel_scene(std::size_t bullets, std::uint64_t seed, bool flat = false);

/// Billiards for pictures: `balls` non-overlapping spheres (radius 2 to 5)
/// in the plane z = 50 of a 100-unit world, every fifth static, the others
/// moving in the plane at 0.5 to 2 units per frame. Deterministic for a seed.
Scene make_billiards_scene(std::size_t balls, std::uint64_t seed);

/// Steps a scene with collision response, using any structure as the broad
/// phase. Owns the structure; the structure holds one object per scene
/// object (user data = object id). Not thread-safe; one step at a time.
class Simulation {
 public:
  /// Inserts every object into `broad_phase` (which must be empty). Throws
  /// std::invalid_argument for a bad configuration.
  Simulation(Scene scene, std::unique_ptr<AnyBroadPhase> broad_phase, SimConfig config = {});

  /// Advances the world by one step of `config.dt`. Cost: one broad-phase
  /// update and pass (off), one per substep tick (substep), or two passes
  /// and one query per event (swept), plus O(n log n) for the ground truth.
  StepStats step();

  /// The current positions and velocities (ids as in the input scene).
  const Scene& scene() const { return scene_; }
  const SimConfig& config() const { return config_; }
  const AnyBroadPhase& broad_phase() const { return *bp_; }

 private:
  struct Event {
    double t;
    std::uint32_t a, b;  ///< b == kWall + axis for a wall
    std::uint32_t va, vb;
  };
  static constexpr std::uint32_t kWall = 0xfffffff0u;

  double inv_mass(std::uint32_t i) const { return inv_mass_[i]; }
  void advance(std::uint32_t i, double from, double duration, StepStats& st);
  bool resolve_overlap(std::uint32_t a, std::uint32_t b, double t, StepStats& st);
  void resolve_pairs(double t, StepStats& st);
  void collect_pairs();
  void sync_movers();
  void step_off(StepStats& st);
  void step_substep(StepStats& st);
  void step_swept(StepStats& st);
  void compute_truth();
  void count_missed(StepStats& st);
  Vec3 position_at(std::uint32_t i, double t) const;
  /// The time of first contact of a and b after `t` on their current
  /// straight paths, within the step; nullopt for a pair already deep in
  /// each other.
  std::optional<double> impact_after(std::uint32_t a, std::uint32_t b, double t) const;
  void push_events_for(std::uint32_t i, double t, StepStats& st);
  void push_wall_event(std::uint32_t i);
  void finish_stats(StepStats& st) const;

  Scene scene_;
  std::unique_ptr<AnyBroadPhase> bp_;
  SimConfig config_;
  std::vector<Handle> handle_;          // by object id
  std::vector<std::uint32_t> id_of_;    // by handle index
  std::vector<std::uint32_t> movers_;   // ids of dynamic objects, ascending
  std::vector<double> inv_mass_;        // 0 for static objects
  std::vector<double> radius_;          // bounding radius
  std::vector<double> first_hit_;       // earliest velocity change in this step
  std::vector<double> local_t_;         // swept: time each mover's position is at
  std::vector<std::uint32_t> version_;  // swept: bumped at each velocity change
  std::vector<int> substeps_;           // substep: ticks per step per mover
  std::vector<Move> moves_;
  std::vector<HandlePair> handle_pairs_;
  std::vector<std::uint64_t> pairs_;     // (min id << 32) | max id, sorted
  std::vector<std::uint64_t> detected_;  // pairs registered in this step
  struct Truth {
    double t;
    std::uint32_t a, b;
  };
  std::vector<Truth> truth_;
  std::vector<Event> events_;  // a min-heap by (t, a, b)
};

}  // namespace broadphase
