/// \file moving.cpp
/// The moving neighbour list of moving_neighbours.hpp: candidates found by
/// the one-shot engine at cutoff + skin, kept while every point stays
/// within skin/2 of its reference position (whole cells aside), and
/// re-evaluated each frame with the exact rule of neighbours.hpp.
#include <algorithm>
#include <broadphase/moving_neighbours.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "frame.hpp"

namespace broadphase {
namespace {

namespace rule = neighbour_rule;
using neighbours_detail::check_cutoff;
using neighbours_detail::number;
using neighbours_detail::parts_for;
using neighbours_detail::reserve_large;
using neighbours_detail::resize_large;
using neighbours_detail::run_parts;

[[noreturn]] void refuse(const std::string& what) { throw InvalidNeighbourInput(what); }

// The largest wrap count a point keeps between rebuilds (it fits the 16
// bits of a Point's m); a point given more cells than this away from its
// reference position rebuilds the list, which is always correct.
constexpr double kMaxWrap = 32767.0;

}  // namespace

MovingNeighbourList::MovingNeighbourList(const NeighbourCell& cell, double cutoff, double skin,
                                         const NeighbourOptions& options)
    : cell_(cell), options_(options), cutoff_(cutoff) {
  check_cutoff(cutoff, "cutoff");
  skin_ = skin < 0 ? kDefaultSkinFraction * cutoff : skin;
  check_cutoff(skin_, "skin");
  reach_ = cutoff + skin_;
  if (!std::isfinite(reach_)) refuse("cutoff + skin: not finite (" + number(reach_) + ")");
  init_frame();
}

MovingNeighbourList::MovingNeighbourList(const NeighbourCell& cell, arrays::Column cutoffs,
                                         std::size_t count, double skin,
                                         const NeighbourOptions& options)
    : cell_(cell), options_(options), per_point_(true) {
  if (cutoffs.empty() && count > 0) refuse("cutoffs: no array given");
  cutoffs_.resize(count);
  double most = 0;
  for (std::size_t i = 0; i < count; ++i) {
    cutoffs_[i] = cutoffs.at(i);
    check_cutoff(cutoffs_[i], "cutoffs[" + std::to_string(i) + "]");
    most = std::max(most, cutoffs_[i]);
  }
  skin_ = skin < 0 ? kDefaultSkinFraction * (most + most) : skin;
  check_cutoff(skin_, "skin");
  // Each point's cutoff grows by half the skin, so that a pair's reach
  // c_i + c_j grows by the skin.
  const double half = 0.5 * skin_;
  build_cutoffs_.resize(count);
  for (std::size_t i = 0; i < count; ++i) build_cutoffs_[i] = cutoffs_[i] + half;
  reach_ = (most + half) + (most + half);
  if (!std::isfinite(reach_)) refuse("cutoffs + skin: not finite (" + number(reach_) + ")");
  init_frame();
}

void MovingNeighbourList::init_frame() {
  const neighbours_detail::Frame f = neighbours_detail::make_frame(cell_);
  // image_offset of the shifts in [-1, 1]^3, the same doubles as computed
  // each time.
  for (std::int64_t a = -1; a <= 1; ++a)
    for (std::int64_t b = -1; b <= 1; ++b)
      for (std::int64_t c = -1; c <= 1; ++c)
        offsets_[static_cast<std::size_t>((a + 1) * 9 + (b + 1) * 3 + (c + 1))] =
            rule::image_offset(cell_, a, b, c);
  inverse_ = f.col;
  for (int k = 0; k < 3; ++k) {
    if (!cell_.periodic[k]) continue;
    const Vec3 v = cell_.vectors[k];
    const double l1 = std::fabs(v.x) + std::fabs(v.y) + std::fabs(v.z);
    spread_sum_ += f.spread[k] * l1;
    cell_sum_ += l1;
  }
}

std::size_t MovingNeighbourList::memory_bytes() const {
  return cutoffs_.capacity() * sizeof(double) + build_cutoffs_.capacity() * sizeof(double) +
         reference_.capacity() * sizeof(Vec3) + points_.capacity() * sizeof(Point) +
         start_.capacity() * sizeof(std::int64_t) + second_.capacity() * sizeof(Candidate) +
         found_.capacity() * sizeof(Candidate) + vectors_.capacity() * sizeof(Vec3);
}

NeighbourList MovingNeighbourList::update(const NeighbourPoints& points) {
  if (per_point_ && points.count != cutoffs_.size())
    refuse("positions: " + std::to_string(points.count) + " points, but the list has " +
           std::to_string(cutoffs_.size()) + " per-point cutoffs");
  if (!built_ || points.count != reference_.size() || !read(points)) rebuild(points);
  return evaluate();
}

// Why the kept candidates hold every pair when `read` accepts a frame.
//
// In real numbers: let u_i = (x_i + m_i·cell) - x_ref,i with |u_i| <= h for
// every point. A pair (i, j, S') of the current points has the vector
// D' = x_j + S'·cell - x_i = (x_ref,j + S·cell - x_ref,i) + u_j - u_i with
// S = S' - m_j + m_i, so the reference pair (i, j, S) is no longer than
// |D'| + 2h; it is a candidate when that is within cutoff + skin, that is
// when 2h <= skin. Its orientation is the same (i < j, or i == j with
// S = S' and the same kept sign), so it is the candidate of that pair.
//
// In floating point: the rule's D, d2 and s*s differ from the real values
// by a few ulps of the magnitudes they add up (|x|, the products S_k·v_k of
// image_offset, the reach); so does the computed |u_i|. With X the largest
// |coordinate| of the reference and current points, and the cell vectors'
// dual columns of length spread_k, |S_k| <= (reach + 2·sqrt(3)·X)·spread_k,
// so every magnitude is below
//   Q = 3X + reach + sum over periodic k of ((reach + 4X)·spread_k + 1)·|v_k|_1.
// The computations are a handful of operations deep: their errors are below
// 64 ulps of Q, about 2^-47·Q. `read` accepts only when every computed
// |u_i| <= h = skin/2·(1 - 2^-40) - 2^-40·Q: the 2^-40·Q taken from each
// point's half of the skin covers the errors of both frames' evaluations of
// a pair and of |u_i| with a factor of about 100 to spare (the same margin
// the one-shot engine's prefilter takes).
bool MovingNeighbourList::read(const NeighbourPoints& p) {
  const std::size_t n = p.count;
  points_.resize(n);
  const arrays::Column cols[3] = {p.x, p.y, p.z};
  double most_x = 0, most_u2 = 0;
  bool wrapped = false;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 x{cols[0].at(i), cols[1].at(i), cols[2].at(i)};
    // Not finite: the rebuild's neighbour_list refuses it with its message.
    if (!(std::isfinite(x.x) && std::isfinite(x.y) && std::isfinite(x.z))) return false;
    most_x = std::max({most_x, std::fabs(x.x), std::fabs(x.y), std::fabs(x.z)});
    const Vec3 r = reference_[i];
    const Vec3 back{r.x - x.x, r.y - x.y, r.z - x.z};
    std::int64_t m[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
      if (!cell_.periodic[k]) continue;
      const Vec3 c = inverse_[static_cast<std::size_t>(k)];
      const double cells = std::nearbyint(back.x * c.x + back.y * c.y + back.z * c.z);
      if (!(std::fabs(cells) <= kMaxWrap)) return false;
      m[k] = static_cast<std::int64_t>(cells);
    }
    Vec3 u{x.x - r.x, x.y - r.y, x.z - r.z};
    if (m[0] != 0 || m[1] != 0 || m[2] != 0) {
      wrapped = true;
      const Vec3 o = rule::image_offset(cell_, m[0], m[1], m[2]);
      u = {(x.x + o.x) - r.x, (x.y + o.y) - r.y, (x.z + o.z) - r.z};
    }
    most_u2 = std::max(most_u2, rule::squared_length(u));
    points_[i] = {x.x,
                  x.y,
                  x.z,
                  {static_cast<std::int16_t>(m[0]), static_cast<std::int16_t>(m[1]),
                   static_cast<std::int16_t>(m[2])},
                  0};
  }
  const double big_x = std::max(most_x, reference_max_);
  const double q = 3 * big_x + reach_ + (reach_ + 4 * big_x) * spread_sum_ + cell_sum_;
  const double h = 0.5 * skin_ * (1 - 0x1p-40) - 0x1p-40 * q;
  wrapped_ = wrapped;
  return h > 0 && most_u2 <= h * h;
}

void MovingNeighbourList::rebuild(const NeighbourPoints& p) {
  NeighbourOptions o;
  o.rule = CutoffRule::inclusive;
  o.full = options_.full;
  o.self_interaction = options_.self_interaction;
  o.threads = options_.threads;
  // The engine's pairs as candidates, without the int64 arrays of a
  // NeighbourList (48 bytes a pair, against 16: at 10^6 points a rebuild
  // made and converted 600 MB of them).
  NeighbourVector<std::int64_t> start;
  const arrays::Column cutoffs = arrays::Column::of(build_cutoffs_.data());
  NeighbourVector<Candidate> second = neighbours_detail::candidate_list(
      p, cell_, reach_, per_point_ ? &cutoffs : nullptr, o, start);
  // candidate_list accepted the points: from here on nothing throws but
  // allocation.
  const std::size_t n = p.count;
  reference_.resize(n);
  // Read at random each frame (a candidate's other point): on huge pages,
  // so that the reads do not also miss the TLB.
  if (points_.capacity() < n) {
    points_.clear();
    reserve_large(points_, n);
  }
  points_.resize(n);
  reference_max_ = 0;
  const arrays::Column cols[3] = {p.x, p.y, p.z};
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 x{cols[0].at(i), cols[1].at(i), cols[2].at(i)};
    reference_[i] = x;
    reference_max_ = std::max({reference_max_, std::fabs(x.x), std::fabs(x.y), std::fabs(x.z)});
    points_[i] = {x.x, x.y, x.z, {0, 0, 0}, 0};
  }
  second_ = std::move(second);
  start_ = std::move(start);
  wrapped_ = false;
  built_ = true;
  ++rebuilds_;
}

NeighbourList MovingNeighbourList::evaluate() {
  const std::size_t n = points_.size();
  const std::size_t total = second_.size();
  const bool one = !per_point_;
  const bool need_d = options_.distances || options_.vectors;
  // Written for every candidate, kept by advancing past it: the branch on
  // the rule, taken about one time in three, and the writes into five
  // growing vectors were most of a frame (perf, 10^5 points). Each part (a
  // range of points, on a thread of its own) keeps its candidates at the
  // front of its own range of them; the output is then written by parts
  // where the counts place them.
  found_.resize(total);
  if (need_d) vectors_.resize(total);
  NeighbourVector<std::int64_t> offsets(n + 1);
  offsets[0] = 0;
  const unsigned parts = parts_for(n, options_.threads);
  const auto part_lo = [&](unsigned p) { return n * p / parts; };
  std::vector<std::size_t> part_kept(parts + 1, 0);
  run_parts(parts, [&](unsigned p) {
    // A candidate's other point is anywhere in memory (points are in the
    // caller's order, not in space): fetched this many candidates ahead,
    // from huge pages (see rebuild). At 10^6 points a frame without a
    // rebuild took 0.26 s with 8 ahead on 4 KiB pages, 0.21 on huge pages,
    // 0.13 to 0.16 with 24 ahead, 0.19 with 48 (one thread).
    constexpr std::size_t kAhead = 24;
    const std::size_t first = part_lo(p), last = part_lo(p + 1);
    const auto base = static_cast<std::size_t>(start_[first]);
    const auto end = static_cast<std::size_t>(start_[last]);
    std::size_t kept = base;
    for (std::size_t i = first; i < last; ++i) {
      const Point& pi = points_[i];
      const Vec3 xi{pi.x, pi.y, pi.z};
      const auto lo = static_cast<std::size_t>(start_[i]);
      const auto hi = static_cast<std::size_t>(start_[i + 1]);
      for (std::size_t e = lo; e < hi; ++e) {
        if (e + kAhead < end) __builtin_prefetch(&points_[second_[e + kAhead].j]);
        const Candidate& c = second_[e];
        const Point& pj = points_[c.j];
        const Vec3 xj{pj.x, pj.y, pj.z};
        std::int64_t s[3] = {c.s[0], c.s[1], c.s[2]};
        if (wrapped_)
          for (int k = 0; k < 3; ++k) s[k] += std::int64_t{pj.m[k]} - std::int64_t{pi.m[k]};
        // The pair is decided in its canonical orientation, as
        // neighbour_list decides it (a full list's mirror takes the
        // canonical vector, negated).
        const bool zero = s[0] == 0 && s[1] == 0 && s[2] == 0;
        const bool canonical =
            i < c.j || (i == c.j && (zero || rule::kept_self_shift(s[0], s[1], s[2])));
        const std::int64_t sign = canonical ? 1 : -1;
        const std::int64_t t[3] = {sign * s[0], sign * s[1], sign * s[2]};
        const bool near =
            t[0] >= -1 && t[0] <= 1 && t[1] >= -1 && t[1] <= 1 && t[2] >= -1 && t[2] <= 1;
        const Vec3 o =
            near ? offsets_[static_cast<std::size_t>((t[0] + 1) * 9 + (t[1] + 1) * 3 + (t[2] + 1))]
                 : rule::image_offset(cell_, t[0], t[1], t[2]);
        const Vec3 d = rule::pair_vector(canonical ? xi : xj, canonical ? xj : xi, o);
        const double reach = one ? cutoff_ : cutoffs_[i] + cutoffs_[c.j];
        const bool pair = rule::within(rule::squared_length(d), reach, options_.rule);
        found_[kept] = {c.j,
                        {static_cast<std::int32_t>(s[0]), static_cast<std::int32_t>(s[1]),
                         static_cast<std::int32_t>(s[2])}};
        if (need_d) vectors_[kept] = canonical ? d : Vec3{-d.x, -d.y, -d.z};
        kept += static_cast<std::size_t>(pair);
      }
      offsets[i + 1] = static_cast<std::int64_t>(kept - base);
    }
    part_kept[p + 1] = kept - base;
  });
  for (unsigned p = 0; p < parts; ++p) part_kept[p + 1] += part_kept[p];
  const std::size_t kept = part_kept[parts];
  NeighbourList out;
  resize_large(out.first, kept);
  resize_large(out.second, kept);
  if (options_.shifts) resize_large(out.shifts, 3 * kept);
  if (options_.distances) resize_large(out.distances, kept);
  if (options_.vectors) resize_large(out.vectors, 3 * kept);
  run_parts(parts, [&](unsigned p) {
    const std::size_t first = part_lo(p), last = part_lo(p + 1);
    const auto base = static_cast<std::size_t>(start_[first]);
    const std::size_t at = part_kept[p];
    // offsets[i + 1] of the part's points: the part's own count so far,
    // made global here (each part reads and writes only its own).
    std::size_t lo = 0;
    for (std::size_t i = first; i < last; ++i) {
      const auto hi = static_cast<std::size_t>(offsets[i + 1]);
      for (std::size_t k = lo; k < hi; ++k) out.first[at + k] = static_cast<std::int64_t>(i);
      offsets[i + 1] = static_cast<std::int64_t>(at + hi);
      lo = hi;
    }
    const std::size_t count = part_kept[p + 1] - at;
    for (std::size_t k = 0; k < count; ++k) {
      const Candidate& f = found_[base + k];
      out.second[at + k] = f.j;
      if (options_.shifts)
        for (int a = 0; a < 3; ++a) out.shifts[3 * (at + k) + a] = f.s[a];
      if (options_.distances)
        out.distances[at + k] = std::sqrt(rule::squared_length(vectors_[base + k]));
      if (options_.vectors)
        for (int a = 0; a < 3; ++a) out.vectors[3 * (at + k) + a] = vectors_[base + k][a];
    }
  });
  if (options_.offsets) out.offsets = std::move(offsets);
  return out;
}

}  // namespace broadphase
