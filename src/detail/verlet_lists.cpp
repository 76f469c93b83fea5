#include <algorithm>
#include <broadphase/detail/sort_keys.hpp>
#include <broadphase/detail/verlet_lists.hpp>
#include <broadphase/detail/worker_pool.hpp>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace broadphase::detail {

namespace {

// Candidate-list margins: the last displacement times kMarginFrames, at
// least kMinMargin of the object's extent, and at most kMaxMargin of the
// larger of its extent and the fixed grid's finest cell. The cell term
// lets tiny fast objects keep a list for several frames (cells that fine
// hold few objects), the extent term keeps lists short in dense crowds.
constexpr double kMarginFrames = 12;
constexpr double kMinMargin = 0.02;
constexpr double kMaxMargin = 0.5;
// A fat box that would not hold a mover for this many frames is not worth
// its margin: the mover is "fast", probes the moving grid every frame and
// keeps no near list (2 against 1.5, 3 and 5: all-moving 20 000
// 2.7 ms against 2.6-4.7, explosion 5.3-5.9 against 4.6-6.2, noisy).
constexpr double kMinFrames = 2;

// A candidate or near pool's capacity for n live entries: room for
// renewals of half as many again.
std::size_t with_room(std::size_t n) { return n + n / 2 + 1024; }

}  // namespace

void VerletLists::move(std::size_t k, const AabbF& b) {
  // The grid entry keeps the fat box; the rebuild renews it if needed.
  Mover& mv = movers_[k];
  mv.speed = displacement(mv.cur, b);
  mv.cur = b;
}

void VerletLists::fixed_grid_rebuilt(const LevelGrid& fixed) {
  ++epoch_;  // every candidate list names entries of the old fixed grid
  finest_cell_ =
      fixed.levels.empty() || !(fixed.levels[0].inv_cell > 0) ? 0 : 1 / fixed.levels[0].inv_cell;
}

VerletLists::Totals VerletLists::refresh_boxes(LevelGrid& moving, std::span<GridEntry> items,
                                               std::span<std::uint32_t> src,
                                               const WorkShares& shares) {
  // The moving grid holds fat boxes: a mover whose bounds left its box gets
  // a new one now (and new lists in renew), a new mover its first.
  ++stamp_;
  // The same pass sums the lengths of the lists that stay and of those to
  // be renewed (movers from the loose list have none), for the pools, and,
  // while no entry is dead, copies each entry to the build's input, at its
  // own index.
  const std::size_t m = moving.entries.size();
  const bool copy = !items.empty();
  moving.bounded = false;  // fat boxes are written in place below
  const unsigned parts = shares.chunks_for(m);
  share_totals_.resize(parts);
  // Read once: the loop writes records that the compiler cannot tell
  // apart from these members.
  const bool direct = direct_, refit = refit_;
  shares.run(parts, [&](unsigned share) {
    Totals sum;
    for (auto [k, end] = slice(m, share, parts); k < end; ++k) {
      GridEntry& e = moving.entries[k];
      if (e.dead()) continue;
      Mover& mv = movers_[k];
      if (direct) {
        // No lists: the entry is the bounds, probed by every other mover.
        mv.fat = mv.cur;
        mv.fast = true;
        mv.guessed = false;
        mv.epoch = epoch_;
        mv.list_begin = mv.list_count = mv.near_begin = mv.near_count = 0;
        std::copy(mv.cur.lo, mv.cur.lo + 3, e.lo);
        std::copy(mv.cur.hi, mv.cur.hi + 3, e.hi);
        if (copy) {
          items[k] = e;
          src[k] = static_cast<std::uint32_t>(k);
        }
        continue;
      }
      // A box made before the speed was known is renewed as soon as it is
      // known (in the first bulk update after the inserts, rather than in
      // a wave over the next frames).
      if (refit || (mv.guessed && mv.speed > 0) || !mv.fat.contains(mv.cur)) {
        mv.fat = fat_box(mv.cur, mv.speed, mv.fast);
        mv.guessed = !(mv.speed > 0);
        mv.epoch = 0;
        std::copy(mv.fat.lo, mv.fat.lo + 3, e.lo);
        std::copy(mv.fat.hi, mv.fat.hi + 3, e.hi);
      }
      const bool keep = mv.epoch == epoch_;
      (keep ? sum.kept : sum.renewing) += mv.list_count;
      (keep ? sum.near_kept : sum.near_renewing) += mv.near_count;
      if (copy) {
        items[k] = e;
        src[k] = static_cast<std::uint32_t>(k);
      }
    }
    share_totals_[share].lists = sum;
  });
  refit_ = false;
  Totals totals;
  for (unsigned k = 0; k < parts; ++k) {
    const Totals& sum = share_totals_[k].lists;
    totals.kept += sum.kept;
    totals.renewing += sum.renewing;
    totals.near_kept += sum.near_kept;
    totals.near_renewing += sum.near_renewing;
  }
  return totals;
}

void VerletLists::set_direct(bool on) {
  if (on == direct_) return;
  direct_ = on;
  if (!on) {
    refit_ = true;
    ++epoch_;  // every mover renews its lists at the next rebuild
  }
}

double VerletLists::renewal_rate(const AabbF& cur, float speed) const {
  // fat_box's margin rule, without the box: a mover moving d a frame with
  // margin M leaves its box after about M / d frames.
  const double travel = speed;
  if (!(travel > 0)) return 0;
  const double extent = extent_of(cur.lo, cur.hi);
  const double cap = kMaxMargin * std::max(extent, finest_cell_);
  if (cap < kMinFrames * travel) return 1;
  const double margin = std::max(std::min(kMarginFrames * travel, cap), kMinMargin * extent);
  return std::min(1.0, travel / margin);
}

double VerletLists::renewal_share(const LevelGrid& moving) const {
  double sum = 0;
  std::size_t live = 0;
  for (std::size_t k = 0; k < movers_.size(); ++k) {
    if (moving.entries[k].dead()) continue;
    ++live;
    sum += renewal_rate(movers_[k].cur, movers_[k].speed);
  }
  return live == 0 ? 0 : sum / static_cast<double>(live);
}

void VerletLists::count_slow(const LevelGrid& moving, const WorkShares& shares) {
  const std::size_t m = moving.entries.size();
  const std::size_t levels = moving.levels.size();
  const unsigned parts = shares.chunks_for(m);
  share_totals_.resize(parts);
  shares.run(parts, [&](unsigned share) {
    std::uint32_t* count = share_totals_[share].count;
    std::fill(count, count + levels, 0);
    auto [k, end] = slice(m, share, parts);
    for (std::size_t l = 0; l < levels && k < end; ++l)
      for (const std::size_t e = std::min(end, moving.level_end(l)); k < e; ++k)
        count[l] += movers_[k].fast ? 0 : 1;
  });
  slow_per_level_.assign(levels, 0);
  for (unsigned k = 0; k < parts; ++k)
    for (std::size_t l = 0; l < levels; ++l) slow_per_level_[l] += share_totals_[k].count[l];
}

AabbF VerletLists::fat_box(const AabbF& cur, float speed, bool& fast) const {
  // A margin that covers several frames of the last displacement, within
  // the limits above.
  const double finest_cell = finest_cell_;
  const double extent = extent_of(cur.lo, cur.hi);
  const double cap = kMaxMargin * std::max(extent, finest_cell);
  const double travel = static_cast<double>(speed);
  double margin = kMarginFrames * travel;
  fast = false;
  if (margin > cap) {
    // A box that would not hold the object for kMinFrames frames only makes
    // every scan wider: such a fast object renews its lists every frame
    // anyway, from a box barely larger than itself.
    fast = cap < kMinFrames * travel;
    margin = fast ? 0 : cap;
  }
  margin = std::max(margin, kMinMargin * extent);
  if (!(margin >= 0)) margin = 0;  // unbounded objects
  // In float: the box only has to contain the bounds (x - m <= x and
  // x + m >= x hold in rounded arithmetic for any m >= 0, infinities
  // included), and the margin itself is a rule of thumb. Rounding each
  // side outwards from double, as before, was a tenth of an all-moving
  // frame in which every mover renews its box (perf, 20 000 objects).
  const auto m = static_cast<float>(margin);
  AabbF g;
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = cur.lo[a] - m;
    g.hi[a] = cur.hi[a] + m;
  }
  return g;
}

void VerletLists::make_room(const LevelGrid& moving, const Totals& totals) {
  // Renewed lists are appended to the pools. When the lists about to be
  // renewed (estimated by their present lengths) would not fit, the lists
  // that stay are moved to the front of each pool, in pool order, in place:
  // the pools keep their memory, so a frame never allocates (nor touches
  // fresh pages) once they have grown to the scene's needs.
  auto stays = [&](std::size_t k) {
    return movers_[k].epoch == epoch_ && !moving.entries[k].dead();
  };
  auto compact = [&](auto& pool, std::uint32_t Mover::*begin, std::uint32_t Mover::*count,
                     std::size_t keep_size, std::size_t add) {
    if (pool.size() + add <= pool.capacity()) return;
    // The lists that stay, in pool order: (begin, mover) keys sorted by
    // begin.
    std::vector<std::uint64_t> order;
    for (std::size_t k = 0; k < movers_.size(); ++k) {
      Mover& mv = movers_[k];
      if (stays(k) && mv.*count > 0)
        order.push_back(std::uint64_t{mv.*begin} << 32 | k);
      else
        mv.*begin = mv.*count = 0;  // empty, renewed below, or dead
    }
    sort_by_high_word(order);
    std::uint32_t w = 0;
    for (const std::uint64_t key : order) {
      Mover& mv = movers_[static_cast<std::uint32_t>(key)];
      std::copy(pool.begin() + mv.*begin, pool.begin() + mv.*begin + mv.*count, pool.begin() + w);
      mv.*begin = w;
      w += mv.*count;
    }
    pool.resize(w);
    // Growth (more or longer lists than before): one allocation with room,
    // rather than doubling.
    if (keep_size + add > pool.capacity()) pool.reserve(with_room(keep_size + add));
  };
  compact(list_pool_, &Mover::list_begin, &Mover::list_count, totals.kept, totals.renewing);
  compact(near_pool_, &Mover::near_begin, &Mover::near_count, totals.near_kept,
          totals.near_renewing);
}

void VerletLists::renew(const LevelGrid& fixed, const LevelGrid& moving, const Totals& totals,
                        const WorkShares& shares, std::span<const Filter> filters) {
  count_slow(moving, shares);
  if (direct_) {
    // No lists: refresh_boxes emptied every live mover's.
    list_pool_.clear();
    near_pool_.clear();
    return;
  }
  const std::size_t m = moving.entries.size();
  const unsigned chunks = shares.chunks_for(m);
  // Each chunk renews the lists of a contiguous range of the moving entries
  // into its own parts (distinct entries share no state; the grids are
  // only read); the parts are appended to the pools in order, so the pools
  // are the same for every thread count.
  make_room(moving, totals);
  const std::size_t list_capacity = list_pool_.capacity();
  const std::size_t near_capacity = near_pool_.capacity();
  if (list_parts_.size() < chunks) {
    list_parts_.resize(chunks);
    near_parts_.resize(chunks);
    renewed_.resize(chunks);
  }
  // The parts are appended as soon as the chunks before them are (while
  // later chunks still renew lists), on whichever thread is free.
  InOrder joined(chunks);
  shares.run(chunks, [&](unsigned c) {
    // Chunk 0 appends to the pools themselves (no other chunk reads them).
    // Each chunk works on vectors on its own stack, moved in and out (as in
    // find_pairs: the vector records lie side by side).
    std::vector<Candidate>& part_home = c == 0 ? list_pool_ : list_parts_[c];
    std::vector<std::uint32_t>& near_home = c == 0 ? near_pool_ : near_parts_[c];
    std::vector<Candidate> part = std::move(part_home);
    std::vector<std::uint32_t> near = std::move(near_home);
    std::vector<std::uint32_t> renewed = std::move(renewed_[c]);
    if (c > 0) {
      part.clear();
      near.clear();
    }
    renewed.clear();
    const auto [begin, end] = slice(m, c, chunks);
    renew_range(fixed, moving, begin, end, part, near, renewed, filters);
    part_home = std::move(part);
    near_home = std::move(near);
    renewed_[c] = std::move(renewed);
    joined.finish(c, [&](unsigned k) {
      if (k == 0) return;  // made in the pools
      const auto offset = static_cast<std::uint32_t>(list_pool_.size());
      const auto near_offset = static_cast<std::uint32_t>(near_pool_.size());
      for (std::uint32_t i : renewed_[k]) {
        movers_[i].list_begin += offset;
        movers_[i].near_begin += near_offset;
      }
      list_pool_.insert(list_pool_.end(), list_parts_[k].begin(), list_parts_[k].end());
      near_pool_.insert(near_pool_.end(), near_parts_[k].begin(), near_parts_[k].end());
      // A wave of renewals (every list after a fixed-grid rebuild) leaves
      // parts far larger than a frame's renewals need: let them go, so
      // that they do not double the lists' memory; the next frames regrow
      // them to their steady size once.
      release_if_oversized(list_parts_[k]);
      release_if_oversized(near_parts_[k]);
      release_if_oversized(renewed_[k]);
    });
  });
  // A pool that had to grow while lists were appended (the first lists, or
  // all of them after a fixed-grid rebuild) keeps room for renewals of half
  // its lists, not what doubling left.
  auto trim = [](auto& pool, std::size_t capacity_before) {
    const std::size_t room = with_room(pool.size());
    if (pool.capacity() == capacity_before || pool.capacity() <= room) return;
    std::remove_reference_t<decltype(pool)> copy;
    copy.reserve(room);
    copy.assign(pool.begin(), pool.end());
    pool.swap(copy);
  };
  trim(list_pool_, list_capacity);
  trim(near_pool_, near_capacity);
}

void VerletLists::renew_range(const LevelGrid& fixed, const LevelGrid& moving, std::size_t begin,
                              std::size_t end, std::vector<Candidate>& part,
                              std::vector<std::uint32_t>& near, std::vector<std::uint32_t>& renewed,
                              std::span<const Filter> filters) {
  // Candidates whose bits fail are left out of the lists: a world of 16
  // layers that mostly ignore each other then reads lists as short as its
  // layers apart would, 1.00-1.03 times their pair time, where testing the
  // bits of every candidate of the full lists took 2.6-4.6 times
  // (bench/filters/layers_bench.cpp, docs/architecture.md).
  for (std::size_t i = begin; i < end; ++i) {
    const GridEntry& e = moving.entries[i];
    Mover& mv = movers_[i];
    if (e.dead()) {
      mv.list_count = mv.near_count = 0;
      continue;
    }
    if (mv.epoch == epoch_) continue;  // the lists cover the object where it is now
    mv.epoch = epoch_;
    mv.stamp = stamp_;
    mv.list_begin = static_cast<std::uint32_t>(part.size());
    fixed.scan(mv.fat, 0, LevelGrid::kNoMinX, [&](std::uint32_t k) {
      if (!bits_pass(filters, e.slot, fixed.entries[k].slot)) return true;
      const Shape& s = fixed.shapes[k];
      part.push_back({{s.center.x, s.center.y, s.center.z},
                      s.kind == ShapeKind::sphere ? s.half.x : Candidate::box_radius(k),
                      fixed.entries[k].handle()});
      return true;
    });
    mv.list_count = static_cast<std::uint32_t>(part.size()) - mv.list_begin;
    // Moving grid entries are fat boxes: this finds every mover whose box
    // overlaps this one's. A fast mover probes the grid every frame instead.
    mv.near_begin = static_cast<std::uint32_t>(near.size());
    if (!mv.fast)
      moving.scan(mv.fat, 0, LevelGrid::kNoMinX, [&](std::uint32_t k) {
        if (k != i && !movers_[k].fast && bits_pass(filters, e.slot, moving.entries[k].slot))
          near.push_back(moving.entries[k].slot);
        return true;
      });
    mv.near_count = static_cast<std::uint32_t>(near.size()) - mv.near_begin;
    renewed.push_back(static_cast<std::uint32_t>(i));
  }
}

std::size_t VerletLists::memory_bytes() const {
  std::size_t bytes = (movers_.capacity() + old_movers_.capacity()) * sizeof(Mover) +
                      list_pool_.capacity() * sizeof(Candidate) + near_pool_.capacity() * 4 +
                      slow_per_level_.capacity() * 4;
  for (const auto& p : list_parts_) bytes += p.capacity() * sizeof(Candidate);
  for (const auto& p : near_parts_) bytes += p.capacity() * 4;
  for (const auto& r : renewed_) bytes += r.capacity() * 4;
  return bytes;
}

void VerletLists::validate(
    const LevelGrid& fixed, const LevelGrid& moving, std::size_t slot_count,
    const std::function<std::optional<std::uint32_t>(std::uint32_t)>& fixed_entry,
    std::span<const Filter> filters, bool current) const {
  auto fail = [](const std::string& what) { throw std::logic_error("grid-verlet: " + what); };
  if (movers_.size() != moving.entries.size()) fail("mover states and moving grid differ");
  for (std::size_t k = 0; k < movers_.size(); ++k) {
    const Mover& mv = movers_[k];
    if (moving.entries[k].dead()) continue;
    if ((current && mv.epoch != epoch_) || mv.stamp > stamp_)
      fail("a mover's lists were not renewed");
    if (static_cast<std::size_t>(mv.near_begin) + mv.near_count > near_pool_.size())
      fail("near list out of the pool");
    if (static_cast<std::size_t>(mv.list_begin) + mv.list_count > list_pool_.size())
      fail("candidate list out of the pool");
    for (std::uint32_t j = 0; j < mv.list_count; ++j) {
      const Candidate& c = list_pool_[mv.list_begin + j];
      if (c.handle.index >= slot_count) fail("candidate names no slot");
      const std::optional<std::uint32_t> k_fixed = fixed_entry(c.handle.index);
      if (!k_fixed) continue;  // the object left the fixed grid
      const GridEntry& o = fixed.entries[*k_fixed];
      const Shape& sh = fixed.shapes[*k_fixed];
      if (!(c.handle == o.handle()) || sh.center.x != c.c[0] || sh.center.y != c.c[1] ||
          sh.center.z != c.c[2] ||
          (sh.is_sphere() ? sh.half.x != c.r : !c.is_box() || c.box_entry() != *k_fixed))
        fail("candidate copy differs from its fixed object");
      if (!o.overlaps(mv.fat)) fail("candidate outside its list's box");
      if (current && !bits_pass(filters, moving.entries[k].slot, c.handle.index))
        fail("candidate whose filter fails");
    }
  }
  if (!current) return;  // the lists are renewed at the next rebuild
  // Every two movers whose fat boxes overlap are in the near list of the
  // one renewed last (the lower slot on a tie): that is what makes the
  // frames exact.
  for (std::size_t i = 0; i < movers_.size(); ++i) {
    const GridEntry& me = moving.entries[i];
    if (me.dead() || movers_[i].fast) continue;
    moving.scan(movers_[i].fat, 0, LevelGrid::kNoMinX, [&](std::uint32_t j) {
      if (j == i || movers_[j].fast || !bits_pass(filters, me.slot, moving.entries[j].slot))
        return true;
      const Mover& a = movers_[i];
      const Mover& b = movers_[j];
      const std::uint32_t sa = me.slot, sb = moving.entries[j].slot;
      const bool a_holds = a.stamp > b.stamp || (a.stamp == b.stamp && sa < sb);
      const Mover& holder = a_holds ? a : b;
      const std::uint32_t other = a_holds ? sb : sa;
      const std::uint32_t* n = near_pool_.data() + holder.near_begin;
      if (std::find(n, n + holder.near_count, other) == n + holder.near_count)
        fail("movers " + std::to_string(sa) + " and " + std::to_string(sb) +
             " overlap in fat boxes but neither near list holds the pair");
      return true;
    });
  }
}

}  // namespace broadphase::detail
