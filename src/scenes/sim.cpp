#include <algorithm>
#include <broadphase/scenes/ccd.hpp>
#include <broadphase/scenes/sim.hpp>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>

namespace broadphase {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

std::uint64_t pair_key(std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | b;
}

double mass_of(const Shape& s) {
  const double r = bounding_radius(s);
  return r * r * r;
}

/// The smallest power of two not below n, at most `cap`.
int pow2_at_least(double n, int cap) {
  int p = 1;
  while (p < cap && p < n) p *= 2;
  return p;
}

}  // namespace

Ccd parse_ccd(std::string_view name) {
  if (name == "off") return Ccd::off;
  if (name == "substep") return Ccd::substep;
  if (name == "swept") return Ccd::swept;
  throw std::invalid_argument("unknown ccd mode '" + std::string(name) +
                              "' (valid: off, substep, swept)");
}

std::string_view to_string(Ccd c) {
  switch (c) {
    case Ccd::off:
      return "off";
    case Ccd::substep:
      return "substep";
    case Ccd::swept:
      return "swept";
  }
  return "?";
}

double kinetic_energy(const Scene& scene) {
  double e = 0;
  for (std::size_t i = 0; i < scene.size(); ++i)
    e += 0.5 * mass_of(scene.objects[i]) * dot(scene.velocity[i], scene.velocity[i]);
  return e;
}

Vec3 momentum(const Scene& scene) {
  Vec3 p;
  for (std::size_t i = 0; i < scene.size(); ++i)
    p = p + scene.velocity[i] * mass_of(scene.objects[i]);
  return p;
}

bool collide(Vec3& va, Vec3& vb, double wa, double wb, const Vec3& n, double k) {
  const double w = wa + wb;
  if (w == 0) return false;
  const double vrel = dot(vb - va, n);
  if (vrel >= 0) return false;  // separating or resting: no impulse
  const double j = -(1 + k) * vrel / w;
  va = va - n * (j * wa);
  vb = vb + n * (j * wb);
  return true;
}

bool bounce(Vec3& v, const Vec3& n, double k) {
  const double vn = dot(v, n);
  if (vn >= 0) return false;
  // v = vp + vn·n  →  vp − k·vn·n, written as v − (1 + k)·vn·n.
  v = v - n * ((1 + k) * vn);
  return true;
}

Scene make_tunnel_scene(std::size_t bullets, std::uint64_t seed, bool flat) {
  Scene s;
  s.world = 200;
  // Three thin layers of small static targets, 20 apart in y and z.
  for (double x : {80.0, 100.0, 120.0})
    for (int iy = 0; iy < 10; ++iy)
      for (int iz = 0; iz < (flat ? 1 : 10); ++iz) {
        s.objects.push_back(Shape::sphere({x, 10.0 + 20 * iy, flat ? 100 : 10.0 + 20 * iz}, 2));
        s.velocity.push_back({0, 0, 0});
      }
  Rng rng(seed);
  for (std::size_t i = 0; i < bullets; ++i) {
    const bool left = rng.uniform() < 0.5;
    const double x = left ? rng.uniform(5, 60) : rng.uniform(140, 195);
    const double y = rng.uniform(5, 195);
    const double z = rng.uniform(5, 195);
    Vec3 dir{left ? 1.0 : -1.0, rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)};
    if (flat) dir.z = 0;
    const double len = std::sqrt(dot(dir, dir));
    const double speed = rng.uniform(8, 25);
    s.objects.push_back(Shape::sphere({x, y, flat ? 100 : z}, 0.5));
    s.velocity.push_back(dir * (speed / len));
  }
  return s;
}

Scene make_billiards_scene(std::size_t balls, std::uint64_t seed) {
  Scene s;
  s.world = 100;
  Rng rng(seed);
  // Rejection sampling; gives up on a ball after many tries so that an
  // impossible count still returns (with fewer balls).
  for (std::size_t i = 0; i < balls; ++i) {
    for (int attempt = 0; attempt < 1000; ++attempt) {
      const double r = rng.uniform(2, 5);
      const Shape b = Shape::sphere({rng.uniform(r, 100 - r), rng.uniform(r, 100 - r), 50}, r);
      bool free = true;
      for (const Shape& o : s.objects) free = free && !overlaps(o, b);
      if (!free) continue;
      s.objects.push_back(b);
      if (i % 5 == 4) {
        s.velocity.push_back({0, 0, 0});
      } else {
        const double angle = rng.uniform(0, 6.283185307179586);
        const double speed = rng.uniform(0.5, 2);
        s.velocity.push_back({speed * std::cos(angle), speed * std::sin(angle), 0});
      }
      break;
    }
  }
  return s;
}

Simulation::Simulation(Scene scene, std::unique_ptr<AnyBroadPhase> broad_phase, SimConfig config)
    : scene_(std::move(scene)), bp_(std::move(broad_phase)), config_(config) {
  if (!bp_) throw std::invalid_argument("simulation: no broad phase");
  if (bp_->size() != 0) throw std::invalid_argument("simulation: the broad phase must be empty");
  if (!(config_.restitution >= 0 && config_.restitution <= 1))
    throw std::invalid_argument("simulation: restitution must be in [0, 1]");
  if (!(config_.dt > 0 && std::isfinite(config_.dt)))
    throw std::invalid_argument("simulation: dt must be positive and finite");
  if (!(config_.substep_fraction > 0) || config_.max_substeps < 1 ||
      config_.max_events_per_mover < 1)
    throw std::invalid_argument("simulation: bad substep or event limits");
  const std::size_t n = scene_.size();
  if (n >= kWall) throw std::invalid_argument("simulation: too many objects");
  handle_.resize(n);
  inv_mass_.resize(n);
  radius_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    const bool moving = scene_.is_moving(i);
    handle_[i] = bp_->insert(scene_.objects[i], i, moving ? Motion::dynamic : Motion::fixed);
    if (handle_[i].index >= id_of_.size()) id_of_.resize(handle_[i].index + 1);
    id_of_[handle_[i].index] = i;
    radius_[i] = bounding_radius(scene_.objects[i]);
    // A zero-radius mover still needs a finite inverse mass.
    inv_mass_[i] = moving ? 1 / std::max(mass_of(scene_.objects[i]), 1e-300) : 0;
    if (moving) movers_.push_back(i);
  }
  first_hit_.assign(n, kInf);
  local_t_.assign(n, 0);
  version_.assign(n, 0);
  substeps_.assign(n, 1);
}

Vec3 Simulation::position_at(std::uint32_t i, double t) const {
  if (inv_mass_[i] == 0) return scene_.objects[i].center;
  return scene_.objects[i].center + scene_.velocity[i] * (t - local_t_[i]);
}

void Simulation::advance(std::uint32_t i, double from, double duration, StepStats& st) {
  Shape& s = scene_.objects[i];
  Vec3& v = scene_.velocity[i];
  const double world = scene_.world;
  const double k = config_.restitution;
  for (int a = 0; a < 3; ++a) {
    double& p = s.center[a];
    const double lo = s.half[a];
    const double hi = world - s.half[a];
    if (lo > hi) {
      // Wider than the world along this axis: it has nowhere to move.
      p = 0.5 * world;
      v[a] = 0;
      continue;
    }
    const double p0 = p;
    const double va = v[a];
    p += va * duration;
    Vec3 n;
    double t_wall;
    if (p < lo && va < 0) {
      n[a] = 1;
      t_wall = p0 > lo ? (lo - p0) / va : 0;
    } else if (p > hi && va > 0) {
      n[a] = -1;
      t_wall = p0 < hi ? (hi - p0) / va : 0;
    } else {
      continue;
    }
    bounce(v, n, k);
    // The rest of the interval at the reflected speed, kept inside the walls.
    const double rest = std::fabs(v[a]) * (duration - t_wall);
    p = n[a] > 0 ? std::min(lo + rest, hi) : std::max(hi - rest, lo);
    first_hit_[i] = std::min(first_hit_[i], from + t_wall);
    ++st.wall_hits;
  }
}

bool Simulation::resolve_overlap(std::uint32_t a, std::uint32_t b, double t, StepStats& st) {
  const double wa = inv_mass_[a];
  const double wb = inv_mass_[b];
  if (wa + wb == 0) return false;
  Shape& sa = scene_.objects[a];
  Shape& sb = scene_.objects[b];
  // Found by the broad phase: registered even if an earlier correction of
  // this pass has separated the two since.
  detected_.push_back(pair_key(a, b));
  if (!overlaps(sa, sb)) return false;
  const Vec3 d = sb.center - sa.center;
  const double dist = std::sqrt(dot(d, d));
  // Identical centres have no normal: push apart along +x, the same for all.
  const Vec3 n = dist > 0 ? d * (1 / dist) : Vec3{1, 0, 0};
  if (collide(scene_.velocity[a], scene_.velocity[b], wa, wb, n, config_.restitution)) {
    ++st.contacts;
    first_hit_[a] = std::min(first_hit_[a], t);
    first_hit_[b] = std::min(first_hit_[b], t);
  }
  const double pen = radius_[a] + radius_[b] - dist;
  if (pen > 0) {
    st.max_penetration = std::max(st.max_penetration, pen);
    sa.center = sa.center - n * (pen * wa / (wa + wb));
    sb.center = sb.center + n * (pen * wb / (wa + wb));
  }
  return true;
}

void Simulation::collect_pairs() {
  pairs_.clear();
  for (const HandlePair& p : handle_pairs_) {
    const std::uint32_t a = id_of_[p.a.index];
    const std::uint32_t b = id_of_[p.b.index];
    if (inv_mass_[a] + inv_mass_[b] == 0) continue;  // two static objects never respond
    pairs_.push_back(pair_key(a, b));
  }
  // The order of resolution must not depend on the structure.
  std::sort(pairs_.begin(), pairs_.end());
  pairs_.erase(std::unique(pairs_.begin(), pairs_.end()), pairs_.end());
}

void Simulation::resolve_pairs(double t, StepStats& st) {
  for (const std::uint64_t key : pairs_)
    resolve_overlap(static_cast<std::uint32_t>(key >> 32), static_cast<std::uint32_t>(key), t, st);
}

void Simulation::sync_movers() {
  moves_.clear();
  for (const std::uint32_t i : movers_) moves_.push_back({handle_[i], scene_.objects[i]});
  bp_->update(moves_);
}

void Simulation::step_off(StepStats& st) {
  const double dt = config_.dt;
  for (const std::uint32_t i : movers_) advance(i, 0, dt, st);
  sync_movers();
  handle_pairs_.clear();
  st.tests += bp_->find_pairs(handle_pairs_).tests;
  st.evaluations = 1;
  collect_pairs();
  resolve_pairs(dt, st);
}

void Simulation::step_substep(StepStats& st) {
  const double dt = config_.dt;
  int ticks = 1;
  for (const std::uint32_t i : movers_) {
    const Vec3& v = scene_.velocity[i];
    const double travel = std::sqrt(dot(v, v)) * dt;
    const double allowed = config_.substep_fraction * radius_[i];
    const double n = allowed > 0 ? travel / allowed : (travel > 0 ? kInf : 1);
    substeps_[i] = pow2_at_least(n, config_.max_substeps);
    ticks = std::max(ticks, substeps_[i]);
  }
  const double h = dt / ticks;
  for (int s = 1; s <= ticks; ++s) {
    moves_.clear();
    for (const std::uint32_t i : movers_) {
      advance(i, (s - 1) * h, h, st);
      // Every count is a power of two dividing `ticks`, so an object with n
      // substeps is due every ticks/n ticks, and everyone is due at the end.
      if (s % (ticks / substeps_[i]) == 0) moves_.push_back({handle_[i], scene_.objects[i]});
    }
    bp_->update(moves_);
    handle_pairs_.clear();
    for (const Move& m : moves_) {
      const Handle self = m.handle;
      st.tests += bp_->query(m.shape,
                             [&](Handle other) {
                               if (!(other == self)) handle_pairs_.push_back({self, other});
                               return true;
                             })
                      .tests;
    }
    ++st.evaluations;
    collect_pairs();
    resolve_pairs(s * h, st);
  }
}

std::optional<double> Simulation::impact_after(std::uint32_t a, std::uint32_t b, double t) const {
  const Vec3 d = position_at(b, t) - position_at(a, t);
  const double s = radius_[a] + radius_[b];
  // A pair already deep in each other (not just touching after an impact)
  // is left to the positional correction at the end of the step: bouncing
  // a body back and forth inside two overlapping static objects at one
  // instant would never advance time.
  if (dot(d, d) < s * s * (1 - 1e-9)) return std::nullopt;
  const auto toi = time_of_impact(d, scene_.velocity[b] - scene_.velocity[a], s, config_.dt - t);
  if (!toi) return std::nullopt;
  return t + *toi;
}

void Simulation::push_wall_event(std::uint32_t i) {
  const Shape& s = scene_.objects[i];
  const Vec3& v = scene_.velocity[i];
  const double t0 = local_t_[i];
  double best = kInf;
  std::uint32_t code = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = s.half[a];
    const double hi = scene_.world - s.half[a];
    if (lo > hi) continue;
    const double p = s.center[a];
    double t = kInf;
    std::uint32_t side = 0;
    if (v[a] < 0) {
      t = p > lo ? t0 + (lo - p) / v[a] : t0;
    } else if (v[a] > 0) {
      t = p < hi ? t0 + (hi - p) / v[a] : t0;
      side = 1;
    }
    if (t < best) {
      best = t;
      code = static_cast<std::uint32_t>(2 * a) + side;
    }
  }
  if (best <= config_.dt) {
    events_.push_back({best, i, kWall + code, version_[i], 0});
    std::push_heap(events_.begin(), events_.end(), [](const Event& x, const Event& y) {
      return std::tie(x.t, x.a, x.b) > std::tie(y.t, y.a, y.b);
    });
  }
}

void Simulation::push_events_for(std::uint32_t i, double t, StepStats& st) {
  const Shape now = Shape{position_at(i, t), scene_.objects[i].half, scene_.objects[i].kind};
  const Shape sweep = swept_shape(now, scene_.velocity[i], config_.dt - t);
  bp_->update(handle_[i], sweep);
  const auto later = [](const Event& x, const Event& y) {
    return std::tie(x.t, x.a, x.b) > std::tie(y.t, y.a, y.b);
  };
  st.tests += bp_->query(sweep,
                         [&](Handle h) {
                           const std::uint32_t j = id_of_[h.index];
                           if (j == i) return true;
                           const std::uint32_t a = std::min(i, j);
                           const std::uint32_t b = std::max(i, j);
                           const auto toi = impact_after(a, b, t);
                           if (toi) {
                             events_.push_back({*toi, a, b, version_[a], version_[b]});
                             std::push_heap(events_.begin(), events_.end(), later);
                           }
                           return true;
                         })
                  .tests;
  push_wall_event(i);
}

void Simulation::step_swept(StepStats& st) {
  const double dt = config_.dt;
  const auto later = [](const Event& x, const Event& y) {
    return std::tie(x.t, x.a, x.b) > std::tie(y.t, y.a, y.b);
  };
  moves_.clear();
  for (const std::uint32_t i : movers_) {
    local_t_[i] = 0;
    moves_.push_back({handle_[i], swept_shape(scene_.objects[i], scene_.velocity[i], dt)});
  }
  bp_->update(moves_);
  handle_pairs_.clear();
  st.tests += bp_->find_pairs(handle_pairs_).tests;
  collect_pairs();
  events_.clear();
  for (const std::uint64_t key : pairs_) {
    const auto a = static_cast<std::uint32_t>(key >> 32);
    const auto b = static_cast<std::uint32_t>(key);
    const auto toi = impact_after(a, b, 0);
    if (toi) events_.push_back({*toi, a, b, version_[a], version_[b]});
  }
  std::make_heap(events_.begin(), events_.end(), later);
  for (const std::uint32_t i : movers_) push_wall_event(i);

  const std::uint64_t budget =
      std::uint64_t(config_.max_events_per_mover) * std::max<std::size_t>(movers_.size(), 1);
  std::uint64_t processed = 0;
  const double k = config_.restitution;
  while (!events_.empty() && processed < budget) {
    std::pop_heap(events_.begin(), events_.end(), later);
    const Event e = events_.back();
    events_.pop_back();
    const bool wall = e.b >= kWall;
    if (version_[e.a] != e.va || (!wall && version_[e.b] != e.vb)) continue;  // outdated
    ++processed;
    // Bring the bodies involved to the event's time.
    const auto move_to = [&](std::uint32_t i) {
      if (inv_mass_[i] == 0) return;
      scene_.objects[i].center = position_at(i, e.t);
      local_t_[i] = e.t;
    };
    if (wall) {
      move_to(e.a);
      Vec3 n;
      const std::uint32_t code = e.b - kWall;
      n[static_cast<int>(code / 2)] = code % 2 == 0 ? 1 : -1;
      if (bounce(scene_.velocity[e.a], n, k)) {
        ++st.wall_hits;
        first_hit_[e.a] = std::min(first_hit_[e.a], e.t);
      }
      ++version_[e.a];
      push_events_for(e.a, e.t, st);
      continue;
    }
    move_to(e.a);
    move_to(e.b);
    detected_.push_back(pair_key(e.a, e.b));
    const Vec3 d = scene_.objects[e.b].center - scene_.objects[e.a].center;
    const double dist = std::sqrt(dot(d, d));
    const Vec3 n = dist > 0 ? d * (1 / dist) : Vec3{1, 0, 0};
    if (collide(scene_.velocity[e.a], scene_.velocity[e.b], inv_mass_[e.a], inv_mass_[e.b], n, k)) {
      ++st.contacts;
      first_hit_[e.a] = std::min(first_hit_[e.a], e.t);
      first_hit_[e.b] = std::min(first_hit_[e.b], e.t);
    }
    for (const std::uint32_t i : {e.a, e.b}) {
      if (inv_mass_[i] == 0) continue;
      ++version_[i];
      push_events_for(i, e.t, st);
    }
  }
  st.evaluations = processed + 1;
  // The rest of the step: linear to the end (walls handled analytically in
  // case the event budget ran out), then the usual overlap pass.
  for (const std::uint32_t i : movers_) {
    advance(i, local_t_[i], dt - local_t_[i], st);
    local_t_[i] = 0;
  }
  sync_movers();
  handle_pairs_.clear();
  st.tests += bp_->find_pairs(handle_pairs_).tests;
  collect_pairs();
  resolve_pairs(dt, st);
}

void Simulation::compute_truth() {
  truth_.clear();
  const std::size_t n = scene_.size();
  std::vector<Aabb> box(n);
  std::vector<std::uint32_t> order(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    const Shape& s = scene_.objects[i];
    box[i] = inv_mass_[i] == 0 ? bounds(s) : bounds(swept_shape(s, scene_.velocity[i], config_.dt));
    order[i] = i;
  }
  // An independent sweep along x: the ground truth does not trust the
  // structure under test.
  std::sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
    return box[x].lo.x < box[y].lo.x || (box[x].lo.x == box[y].lo.x && x < y);
  });
  std::vector<std::uint32_t> active;
  for (const std::uint32_t i : order) {
    std::size_t keep = 0;
    for (const std::uint32_t j : active)
      if (box[j].hi.x >= box[i].lo.x) active[keep++] = j;
    active.resize(keep);
    for (const std::uint32_t j : active) {
      if (inv_mass_[i] + inv_mass_[j] == 0 || !box[i].overlaps(box[j])) continue;
      const std::uint32_t a = std::min(i, j);
      const std::uint32_t b = std::max(i, j);
      const Shape& sa = scene_.objects[a];
      const Shape& sb = scene_.objects[b];
      if (!sa.is_sphere() || !sb.is_sphere() || overlaps(sa, sb)) continue;
      const auto toi =
          time_of_impact(sb.center - sa.center, scene_.velocity[b] - scene_.velocity[a],
                         radius_[a] + radius_[b], config_.dt);
      if (toi) truth_.push_back({*toi, a, b});
    }
    active.push_back(i);
  }
}

void Simulation::count_missed(StepStats& st) {
  std::sort(detected_.begin(), detected_.end());
  for (const Truth& t : truth_) {
    const bool seen = std::binary_search(detected_.begin(), detected_.end(), pair_key(t.a, t.b));
    // Before either body changed velocity, both followed the straight paths
    // the truth was computed on, so the contact certainly happened.
    const bool happened = t.t <= std::min(first_hit_[t.a], first_hit_[t.b]);
    if (seen || happened) ++st.true_contacts;
    if (happened && !seen) ++st.missed;
  }
}

void Simulation::finish_stats(StepStats& st) const {
  st.kinetic_energy = kinetic_energy(scene_);
  st.momentum = momentum(scene_);
}

StepStats Simulation::step() {
  StepStats st;
  if (config_.measure_missed) compute_truth();
  std::fill(first_hit_.begin(), first_hit_.end(), kInf);
  detected_.clear();
  const auto start = std::chrono::steady_clock::now();
  switch (config_.ccd) {
    case Ccd::off:
      step_off(st);
      break;
    case Ccd::substep:
      step_substep(st);
      break;
    case Ccd::swept:
      step_swept(st);
      break;
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (config_.measure_missed) count_missed(st);
  finish_stats(st);
  return st;
}

}  // namespace broadphase
