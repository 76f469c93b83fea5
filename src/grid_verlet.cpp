#include <atomic>
#include <broadphase/detail/worker_pool.hpp>
#include <broadphase/grid_verlet.hpp>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>

namespace broadphase {

namespace {

// Cells per level at most this many times its objects (a level of few
// objects over a wide world gets larger cells instead of empty ones).
constexpr double kCellsPerObject = 2;
// The moving grid holds fat boxes, probed by every fast mover each frame:
// finer cells there pay for their memory (explosion 20 000: 8.3 -> 6.3 ms).
constexpr double kMovingCellsPerObject = 8;
// Dense mode (grid_verlet.hpp) from this expected share of movers renewing
// their lists each frame while fixed objects are no more than the movers,
// and back to lists below kDenseUntil or beyond twice as many fixed
// objects; the share is looked at every kModeEvery bulk updates (and at
// the second, the first that knows the movers' speeds). Measured frame
// times, dense over lists (one thread, 2-core EPYC VM, medians of 60-100
// frames): all-moving 20 000 (no fixed objects) 0.99 at share 0.09, 0.91
// at 0.14, 0.82 at 0.25, 0.65 at 0.45 (the lab's), 0.59 at 0.72;
// explosion (0.95) 0.72. With fixed objects every mover probes the fixed
// grid each frame instead of reading a list: the lab's worlds with slow
// movers (share 0.083) 1.3-4.5, and with their movers sped up 10 and 40
// times: 4 fixed objects a mover, clusters 0.63 and 0.78, the study's
// even world 1.08 (share 0.21) and 0.86; the city (2.3 a mover, large
// buildings) 1.23 (share 0.68) and 1.09 (0.95).
constexpr double kDenseFrom = 0.3;
constexpr double kDenseUntil = 0.2;
constexpr std::uint32_t kModeEvery = 8;
// Loose and held-back objects tolerated before a mutation rebuilds.
constexpr std::size_t kMinLoose = 64;
// Threads at most (option threads=N, and hardware concurrency for N = 0).
constexpr unsigned kMaxThreads = GridVerletOptions::kMaxThreads;
constexpr unsigned kChunksPerShare = detail::WorkShares::kChunksPerShare;
using detail::displacement;
using detail::extent_of;
using detail::release_if_oversized;
using detail::Slice;
using detail::slice;

}  // namespace

void GridVerletOptions::check() const {
  detail::check_integer("grid-verlet", "threads", threads, 0, kMaxThreads);
  detail::check_number("grid-verlet", "cell", cell, 0.5, 64);
  detail::check_integer("grid-verlet", "grain", grain, 1, std::uint64_t{1} << 24);
}

namespace {
// The configuration and options checked, in that order, then the thread
// count they ask for.
unsigned threads_of(const Config& c, const GridVerletOptions& o) {
  check_config(c, "grid-verlet");
  o.check();
  if (o.threads == 0) return std::clamp(std::thread::hardware_concurrency(), 1u, kMaxThreads);
  return o.threads;
}
}  // namespace

GridVerlet::GridVerlet(const Config& c, const GridVerletOptions& o)
    : shares_(threads_of(c, o), o.grain),
      fixed_spec_{c.world, o.cell, kCellsPerObject},
      moving_spec_{fixed_spec_.world, o.cell, kMovingCellsPerObject},
      movers_option_(o.movers) {
  if (o.movers == GridVerletMovers::dense) {
    dense_mode_ = true;
    lists_.set_direct(true);
    refill_dense();  // empty
  }
  if (c.expected_objects > 0) {
    const std::size_t n = c.expected_objects;
    user_.reserve(n);
    slots_.reserve(n);
  }
}

GridVerlet::~GridVerlet() = default;

std::uint32_t GridVerlet::allocate_slot() {
  std::uint32_t s;
  if (free_head_ != Handle::kNullIndex) {
    s = free_head_;
    free_head_ = static_cast<std::uint32_t>(user_[s]);
  } else {
    if (slots_.size() >= Handle::kNullIndex)
      throw std::length_error("grid-verlet: too many objects");
    s = static_cast<std::uint32_t>(slots_.size());
    user_.push_back(0);
    slots_.emplace_back();
  }
  ++slots_[s].gen;  // even (free) -> odd (alive)
  ++live_;
  if (s < filters_.size()) filters_[s] = Filter{};
  return s;
}

void GridVerlet::set_filter(Handle h, Filter f) {
  const std::uint32_t s = index_of(h);
  if (filters_.empty() && f == Filter{}) return;
  if (filters_.size() < slots_.size()) filters_.resize(slots_.size());
  if (filters_[s] == f) return;
  filters_[s] = f;
  // The cache of fixed pairs holds only pairs that pass; the movers' lists
  // leave out candidates that failed: both are incomplete now. The lists
  // are all renewed at the next rebuild, and until then the frames do
  // without them.
  if (slots_[s].home == Home::fixed_grid) drop_fixed_cache();
  if (dense_mode_ && slots_[s].home == Home::moving_grid)
    dense_->set_filter(dense_handle_[slots_[s].pos], f);
  lists_.fixed_grid_rebuilt(fixed_);
  lists_stale_ = true;
}

void GridVerlet::set_pair_filter(PairFilter pf) {
  pair_filter_ = std::move(pf);
  drop_fixed_cache();
}

void GridVerlet::drop_fixed_cache() {
  if (!cache_built_) return;
  fixed_pairs_.clear();
  cache_built_ = false;
}

void GridVerlet::free_slot(std::uint32_t s) {
  slots_[s].home = Home::free;
  user_[s] = free_head_;
  free_head_ = s;
}

void GridVerlet::add_loose(std::uint32_t s, const Shape& shape) {
  slots_[s].home = Home::loose;
  slots_[s].pos = static_cast<std::uint32_t>(loose_.size());
  loose_.push_back(s);
  loose_bounds_.push_back(bounds_f(shape));
  loose_shapes_.push_back(shape);
  loose_speed_.push_back(0);  // unknown until it moves again
}

void GridVerlet::drop_loose(std::uint32_t s) {
  const std::uint32_t p = slots_[s].pos;
  const std::uint32_t last = loose_.back();
  loose_[p] = last;
  loose_bounds_[p] = loose_bounds_.back();
  loose_shapes_[p] = loose_shapes_.back();
  loose_speed_[p] = loose_speed_.back();
  slots_[last].pos = p;
  loose_.pop_back();
  loose_bounds_.pop_back();
  loose_shapes_.pop_back();
  loose_speed_.pop_back();
}

void GridVerlet::leave_grid(std::uint32_t s) {
  Grid* g = nullptr;
  if (slots_[s].home == Home::fixed_grid) {
    --fixed_count_;
    fixed_dirty_ = true;  // its cached pairs must go at the next rebuild
    g = &fixed_;
  } else if (slots_[s].home == Home::moving_grid) {
    --moving_count_;
    g = &moving_;
    if (dense_mode_) dense_->remove(dense_handle_[slots_[s].pos]);
  }
  if (g != nullptr) {
    Entry& e = g->entries[slots_[s].pos];
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::fill(e.lo, e.lo + 3, nan);
    std::fill(e.hi, e.hi + 3, nan);
  }
}

Handle GridVerlet::insert(const Shape& s, std::uint64_t user, Motion m) {
  require_valid(s);
  const std::uint32_t i = allocate_slot();
  user_[i] = user;
  slots_[i].motion = m;
  add_loose(i, s);
  if (m == Motion::fixed) fixed_dirty_ = true;
  maybe_rebuild();
  return {i, slots_[i].gen};
}

void GridVerlet::remove(Handle h) {
  const std::uint32_t s = index_of(h);
  ++slots_[s].gen;  // odd -> even: every handle to the object is stale from now on
  --live_;
  if (slots_[s].home == Home::loose) {
    drop_loose(s);
    free_slot(s);
    return;
  }
  // A grid entry still names this slot: hold the slot back until the grid
  // is rebuilt, so that it cannot be handed to a new object meanwhile.
  leave_grid(s);
  slots_[s].home = Home::held;
  held_.push_back(s);
  maybe_rebuild();
}

void GridVerlet::update(Handle h, const Shape& s) {
  const std::uint32_t i = index_of(h);
  require_valid(s);
  const bool was_loose = slots_[i].home == Home::loose;
  move_via_loose(i, s);
  if (!was_loose) maybe_rebuild();
}

void GridVerlet::move_mover(std::uint32_t k, const Shape& shape) {
  if (dense_mode_) {
    // The dense grid alone: its slots follow ours, so moves given in the
    // order of the handles read and write it front to back (the moving
    // grid's records, in cell order, would cost a miss each).
    const Handle d = dense_handle_[k];
    const AabbF before = dense_->bounds_at(d.index);
    dense_->update(d, shape);
    dense_speed_[d.index] = detail::displacement(before, dense_->bounds_at(d.index));
    return;
  }
  lists_.move(k, bounds_f(shape));
  moving_.shapes[k] = shape;
}

bool GridVerlet::stage_dense(std::uint32_t k, const Shape& shape, AabbF& b,
                             detail::OccupiedBox& grown) {
  const Handle d = dense_handle_[k];
  const AabbF before = dense_->bounds_at(d.index);
  const bool done = dense_->stage_update(d, shape, b, grown);
  dense_speed_[d.index] = detail::displacement(before, b);
  return done;
}

void GridVerlet::move_via_loose(std::uint32_t i, const Shape& shape) {
  slots_[i].motion = Motion::dynamic;  // a fixed object that moves is moving from now on
  if (slots_[i].home != Home::loose) {
    leave_grid(i);
    add_loose(i, shape);
    return;
  }
  const std::uint32_t p = slots_[i].pos;
  const AabbF b = bounds_f(shape);
  loose_speed_[p] = displacement(loose_bounds_[p], b);
  loose_bounds_[p] = b;
  loose_shapes_[p] = shape;
}

void GridVerlet::update(std::span<const Move> moves) {
  // Passes over the moves, in chunks taken by whichever thread is free: the
  // first checks every move (nothing changes if one is bad: the checks are
  // then repeated on one thread, for the error) and notes each one's mover;
  // the last moves the movers, each chunk those of its moves, which it
  // reads front to back. A handle named twice must be moved by one thread,
  // in order: on several threads the first pass also marks each moved
  // object's slot with its chunk, a second pass finds any mark overwritten
  // (by another chunk) or met again (in a chunk), and then each share takes
  // instead every move into its range of movers. The marks go by slot, the
  // place the move names: by mover, each mark waited for the slot's load,
  // which doubled the first pass. Movers stay movers here; the other
  // objects, which change home, move afterwards, in order. The passes
  // prefetch ahead: the moves come in the caller's order, the slots and
  // movers they name are scattered.
  constexpr std::uint32_t kOther = 0xFFFFFFFFu;
  constexpr std::size_t kAhead = 16;
  const std::size_t m = moving_.entries.size();
  const std::size_t n = moves.size();
  const unsigned t = shares_.shares_for(std::min(n, m));
  const unsigned chunks = shares_.chunks_for(std::min(n, m));
  // Not the grid build's tag array: that one's lines are written pass
  // after pass by the thread that owns the same range of the moving grid,
  // and would cross between the cores were they first written in the
  // moves' order.
  std::vector<std::uint32_t>& target = move_target_;
  target.resize(n);
  // A chunk's mark: this update's round and the chunk. Marks are written
  // and read through relaxed atomics: two chunks may write one mover's.
  static_assert(kMaxThreads * kChunksPerShare <= 1024, "a mark holds the chunk in 10 bits");
  const bool marks = t > 1;
  if (marks) {
    mark_.resize(slots_.size());
    if (++mark_round_ >= (1u << 22)) {  // wrapped: no entry may hold a current mark
      std::fill(mark_.begin(), mark_.end(), 0);
      mark_round_ = 1;
    }
  }
  auto mark = [&](std::uint32_t p) { return std::atomic_ref<std::uint32_t>(mark_[p]); };
  const std::uint32_t round = mark_round_ << 10;
  std::atomic<bool> bad{false}, others{false}, twice{false};
  shares_.run(chunks, [&](unsigned c) {
    bool any_other = false, any_twice = false;
    for (auto [j, end] = slice(n, c, chunks); j < end; ++j) {
      if (j + kAhead < end && moves[j + kAhead].handle.index < slots_.size())
        detail::prefetch(&slots_[moves[j + kAhead].handle.index]);
      const Handle h = moves[j].handle;
      if (!contains(h) || !is_valid(moves[j].shape)) {
        bad = true;
        return;
      }
      const Slot& sl = slots_[h.index];
      target[j] = sl.home == Home::moving_grid ? sl.pos : kOther;
      if (target[j] == kOther) {
        any_other = true;
      } else if (marks) {
        any_twice |= mark(h.index).load(std::memory_order_relaxed) == (round | c);
        mark(h.index).store(round | c, std::memory_order_relaxed);
      }
    }
    if (any_other) others = true;
    if (any_twice) twice = true;
  });
  if (bad) {
    for (const Move& mv : moves) {
      index_of(mv.handle);
      require_valid(mv.shape);
    }
  }
  if (marks && !twice)
    shares_.run(chunks, [&](unsigned c) {
      bool any_twice = false;
      for (auto [j, end] = slice(n, c, chunks); j < end; ++j)
        any_twice |= target[j] != kOther &&
                     mark(moves[j].handle.index).load(std::memory_order_relaxed) != (round | c);
      if (any_twice) twice = true;
    });
  // Moves [first, last) to movers in [lo, hi).
  auto move_range = [&](Slice of_moves, Slice of_movers) {
    const auto [first, last] = of_moves;
    const auto [lo, hi] = of_movers;
    for (std::size_t j = first; j < last; ++j) {
      if (j + kAhead < last) {
        const std::uint32_t a = target[j + kAhead];
        if (a >= lo && a < hi) {
          detail::prefetch(&lists_.movers()[a].cur);
          detail::prefetch(&lists_.movers()[a].speed);  // often on the record's second line
          detail::prefetch(&moving_.shapes[a]);
        }
      }
      const std::uint32_t p = target[j];
      if (p >= lo && p < hi) move_mover(p, moves[j].shape);
    }
  };
  if (dense_mode_ && (t <= 1 || twice)) {
    // The dense grid's lists are changed in place, by one thread.
    for (std::size_t j = 0; j < n; ++j)
      if (target[j] != kOther) move_mover(target[j], moves[j].shape);
  } else if (dense_mode_) {
    // Every move's shape and bounds on the threads, with the whole move for
    // those that keep their cells; the others relink the dense grid's
    // lists, on this thread, after them, in the moves' order, which leaves
    // the lists as the moves one after another would. (Explosion 20 000:
    // the relinks are most moves, and a third of the update.)
    if (dense_later_.size() < chunks) dense_later_.resize(chunks);
    dense_grown_.assign(chunks, detail::OccupiedBox{});
    shares_.run(chunks, [&](unsigned c) {
      auto& later = dense_later_[c];
      detail::OccupiedBox grown;  // on this thread's stack: the chunks' records lie side by side
      later.clear();
      for (auto [j, end] = slice(n, c, chunks); j < end; ++j) {
        AabbF b;
        if (target[j] != kOther && !stage_dense(target[j], moves[j].shape, b, grown))
          later.push_back({static_cast<std::uint32_t>(j), b});
      }
      dense_grown_[c] = grown;
    });
    for (unsigned c = 0; c < chunks; ++c) dense_->cover(dense_grown_[c]);
    for (unsigned c = 0; c < chunks; ++c)
      for (const auto& [j, b] : dense_later_[c]) dense_->relink(dense_handle_[target[j]], b);
  } else if (twice)
    shares_.run(t, [&](unsigned k) { move_range({0, n}, slice(m, k, t)); });
  else
    shares_.run(chunks, [&](unsigned c) { move_range(slice(n, c, chunks), {0, m}); });
  if (others)
    for (std::size_t j = 0; j < n; ++j)
      if (target[j] == kOther) move_via_loose(moves[j].handle.index, moves[j].shape);
  choose_mover_mode();
  settle();
}

void GridVerlet::settle() {
  // In dense mode the movers are current in the dense grid: the moving
  // grid is rebuilt only when objects join or leave it, or the mode changes.
  if (!dense_mode_ || mode_changed_ || fixed_dirty_ || !loose_.empty() || !held_.empty())
    rebuild(fixed_dirty_);
  if (!cache_built_) build_fixed_cache();
}

void GridVerlet::choose_mover_mode() {
  if (movers_option_ != GridVerletMovers::automatic) return;
  ++bulk_updates_;
  if (bulk_updates_ % kModeEvery != 2 % kModeEvery) return;
  // In dense mode the movers' bounds and speeds are the dense grid's, read
  // where they are (copying them back every look cost 0.3 ms at 20 000).
  double share = 0;
  if (dense_mode_) {
    for (std::size_t k = 0; k < moving_.entries.size(); ++k) {
      if (moving_.entries[k].dead()) continue;
      const Handle d = dense_handle_[k];
      share += lists_.renewal_rate(dense_->bounds_at(d.index), dense_speed_[d.index]);
    }
    share = moving_count_ == 0 ? 0 : share / static_cast<double>(moving_count_);
  } else {
    share = lists_.renewal_share(moving_);
  }
  const bool dense = dense_mode_ ? share >= kDenseUntil && fixed_count_ <= 2 * moving_count_
                                 : share > kDenseFrom && fixed_count_ <= moving_count_;
  if (dense == dense_mode_) return;
  dense_mode_ = dense;
  mode_changed_ = true;
  lists_.set_direct(dense);
  if (!dense) {
    sync_from_dense();  // the movers as they are now, for the rebuild with lists
    dense_.reset();
    dense_handle_ = {};
    dense_speed_ = {};
  }
}

void GridVerlet::refill_dense() {
  // The dense grid is made afresh for the movers of the new moving grid:
  // rebuilds are rare in dense mode (objects joining or leaving). Movers
  // go in in the order of our slots, which its slots then follow.
  Config c;
  c.world = fixed_spec_.world;
  c.expected_objects = moving_count_;
  dense_ = std::make_unique<GridDense>(c, GridDenseOptions{});
  dense_handle_.assign(moving_.entries.size(), Handle{});
  dense_speed_.clear();
  for (std::uint32_t s = 0; s < slots_.size(); ++s) {
    if (slots_[s].home != Home::moving_grid) continue;
    const std::uint32_t k = slots_[s].pos;
    const Handle d = dense_->insert(moving_.shapes[k], pack(handle_of(s)));
    dense_handle_[k] = d;
    if (!filters_.empty()) dense_->set_filter(d, filter_of(s));
    if (d.index >= dense_speed_.size()) dense_speed_.resize(d.index + 1);
    dense_speed_[d.index] = lists_.movers()[k].speed;
  }
}

void GridVerlet::sync_from_dense() {
  for (std::size_t k = 0; k < moving_.entries.size(); ++k) {
    if (moving_.entries[k].dead()) continue;
    const Handle d = dense_handle_[k];
    moving_.shapes[k] = dense_->shape(d);
    lists_.place(k, dense_->bounds_at(d.index), dense_speed_[d.index]);
  }
}

void GridVerlet::maybe_rebuild() {
  if (loose_.size() + held_.size() > std::max(kMinLoose, live_ / 8)) {
    // The pair cache waits for the next bulk update: while objects stream
    // in, every threshold rebuild would otherwise recompute it.
    rebuild(fixed_dirty_);
  }
}

void GridVerlet::rebuild(bool fixed_too) {
  if (dense_mode_ && !mode_changed_) sync_from_dense();  // the movers as they are now
  auto take_loose = [&](Motion m, std::vector<Entry>& items, std::vector<std::uint32_t>& src) {
    for (std::size_t k = 0; k < loose_.size(); ++k) {
      const std::uint32_t s = loose_[k];
      if (slots_[s].motion != m) continue;
      Entry e{};
      std::copy(loose_bounds_[k].lo, loose_bounds_[k].lo + 3, e.lo);
      std::copy(loose_bounds_[k].hi, loose_bounds_[k].hi + 3, e.hi);
      e.slot = s;
      e.gen = slots_[s].gen;
      items.push_back(e);
      src.push_back(kFromLoose | static_cast<std::uint32_t>(k));
    }
  };
  auto take_grid = [](const Grid& g, std::vector<Entry>& items, std::vector<std::uint32_t>& src) {
    for (std::size_t k = 0; k < g.entries.size(); ++k) {
      if (g.entries[k].dead()) continue;
      items.push_back(g.entries[k]);
      src.push_back(static_cast<std::uint32_t>(k));
    }
  };
  if (fixed_too) {
    // The fixed grid is rebuilt rarely: its inputs are temporaries of the
    // exact size, so the kept scratch arrays stay as small as the moving set.
    std::vector<Entry> items;
    std::vector<std::uint32_t> src;
    items.reserve(fixed_count_ + loose_.size());
    src.reserve(fixed_count_ + loose_.size());
    take_grid(fixed_, items, src);
    take_loose(Motion::fixed, items, src);
    std::vector<LineShape> old_shapes;
    old_shapes.swap(fixed_.shapes);
    Grid::Scratch scratch;
    const std::span<const std::uint32_t> at = fixed_.build(items, fixed_spec_, shares_, scratch);
    const unsigned chunks = shares_.chunks_for(items.size());
    shares_.run(chunks, [&](unsigned c) {
      for (auto [i, end] = slice(items.size(), c, chunks); i < end; ++i)
        fixed_.shapes[at[i]] = shape_from(src[i], old_shapes);
    });
    point_slots(fixed_, Home::fixed_grid);
    fixed_count_ = fixed_.entries.size();
    fixed_pairs_.clear();
    fixed_pairs_.shrink_to_fit();
    cache_built_ = false;
    fixed_dirty_ = false;
    lists_.fixed_grid_rebuilt(fixed_);  // every list names entries of the old grid
  }
  // The moving grid holds fat boxes: a mover whose bounds left its box gets
  // a new one now (and new lists below), a new mover its first. The same
  // pass, while no entry is dead, copies each entry to the build's input,
  // at its own index (else a pass on one thread gathers the live ones).
  const std::size_t m = moving_.entries.size();
  const bool none_dead = moving_count_ == m;
  std::vector<Entry>& items = scratch_items_;
  std::vector<std::uint32_t>& src = scratch_src_;
  if (none_dead) {
    items.resize(m);  // no work when the size stays, as from frame to frame
    src.resize(m);
  } else {
    items.clear();
    src.clear();
  }
  const detail::VerletLists::Totals totals =
      none_dead ? lists_.refresh_boxes(moving_, items, src, shares_)
                : lists_.refresh_boxes(moving_, {}, {}, shares_);
  if (!none_dead) take_grid(moving_, items, src);
  const std::size_t first_loose = items.size();
  take_loose(Motion::dynamic, items, src);
  // Without lists a new mover's entry is its bounds, as every mover's.
  for (std::size_t i = first_loose; !lists_.direct() && i < items.size(); ++i) {
    // A loose object that moved since it was inserted has a known speed.
    bool fast;
    const AabbF f = lists_.fat_box(items[i].box(), loose_speed_[src[i] & ~kFromLoose], fast);
    std::copy(f.lo, f.lo + 3, items[i].lo);
    std::copy(f.hi, f.hi + 3, items[i].hi);
  }
  scratch_shapes_.swap(moving_.shapes);
  lists_.reorder(items.size());
  const std::span<const std::uint32_t> at =
      moving_.build(items, moving_spec_, shares_, moving_scratch_);
  // Each item's shape and mover record go where the build put it (the
  // items of a chunk went to distinct entries).
  const unsigned chunks = shares_.chunks_for(items.size());
  shares_.run(chunks, [&](unsigned c) {
    for (auto [i, end] = slice(items.size(), c, chunks); i < end; ++i) {
      const std::uint32_t k = at[i];
      const std::uint32_t from = src[i];
      moving_.shapes[k] = shape_from(from, scratch_shapes_);
      if ((from & kFromLoose) != 0) {
        const std::uint32_t l = from & ~kFromLoose;
        lists_.start(k, loose_bounds_[l], loose_speed_[l], items[i].box());
      } else {
        lists_.keep(k, from);
      }
    }
  });
  point_slots(moving_, Home::moving_grid);
  moving_count_ = moving_.entries.size();
  lists_.renew(fixed_, moving_, totals, shares_, filters_);
  lists_stale_ = false;  // every list not renewed now was renewed since the last filter change
  if (dense_mode_) refill_dense();
  mode_changed_ = false;
  // The loose list can grow to an eighth of the objects while a scene is
  // inserted; kept after the build it would hold 11 bytes per object for
  // single inserts that seldom come.
  loose_.clear();
  loose_bounds_.clear();
  loose_shapes_.clear();
  loose_speed_.clear();
  release_if_oversized(loose_);
  release_if_oversized(loose_bounds_);
  release_if_oversized(loose_shapes_);
  release_if_oversized(loose_speed_);
  for (std::uint32_t s : held_) free_slot(s);
  held_.clear();
  release_if_oversized(held_);
}

void GridVerlet::point_slots(const Grid& g, Home home) {
  // Every slot is named by one entry: the shares write distinct records.
  const std::size_t n = g.entries.size();
  const unsigned parts = shares_.chunks_for(n);
  shares_.run(parts, [&](unsigned share) {
    for (auto [k, end] = slice(n, share, parts); k < end; ++k) {
      Slot& sl = slots_[g.entries[k].slot];
      sl.home = home;
      sl.pos = static_cast<std::uint32_t>(k);
    }
  });
}

inline const Shape& GridVerlet::shape_from(std::uint32_t src,
                                           const std::vector<LineShape>& old_shapes) const {
  return (src & kFromLoose) != 0 ? loose_shapes_[src & ~kFromLoose]
                                 : static_cast<const Shape&>(old_shapes[src]);
}

void GridVerlet::build_fixed_cache() {
  fixed_pairs_.clear();
  std::uint64_t tests = 0;
  auto emit = [this](Handle a, Handle b) {
    fixed_pairs_.push_back({a, b});
    return true;
  };
  // The cache holds only pairs that pass the filters: a filter change
  // drops it (set_filter, set_pair_filter).
  if (unfiltered()) {
    grid_pairs(fixed_, 0, fixed_.entries.size(), emit, tests);
  } else {
    auto gate = gated<true>(emit);
    grid_pairs(fixed_, 0, fixed_.entries.size(), gate, tests);
  }
  fixed_pairs_.shrink_to_fit();  // the cache is kept until the fixed set changes
  cache_built_ = true;
}

QueryCost GridVerlet::find_pairs(std::vector<HandlePair>& out) const {
  return unfiltered() ? find_pairs_as<false>(out) : find_pairs_as<true>(out);
}

template <bool kFiltered>
QueryCost GridVerlet::find_pairs_as(std::vector<HandlePair>& out) const {
  QueryCost cost;
  auto emit_out = gated<kFiltered>([&out](Handle a, Handle b) {
    out.push_back({a, b});
    return true;
  });
  auto emit_fixed = [&] {
    if (cache_built_ && fixed_count_ == fixed_.entries.size()) {
      // Every cached handle is still current: a fixed object can only change
      // its generation by leaving the grid.
      out.insert(out.end(), fixed_pairs_.begin(), fixed_pairs_.end());
      return;
    }
    if (cache_built_) out.reserve(out.size() + fixed_pairs_.size());
    fixed_pairs(emit_out, cost.tests);
  };

  // On threads: job 0 emits the fixed pairs straight into `out`; the
  // movers' pairs are found by the other jobs, `pieces` of them, each by
  // find(piece, emit, tests) into the piece's own buffer. The pieces, fixed
  // pairs first, then the others in order (the order of one thread), are
  // appended while later pieces are still being found (appended by the
  // caller after the run, they took 0.09 ms of a 3 ms two-thread frame at
  // scaled-even 102 400).
  auto in_pieces = [&](unsigned pieces, auto find) {
    std::unique_lock lock(buffers_mutex_, std::try_to_lock);
    std::vector<std::vector<HandlePair>> local;
    std::vector<std::vector<HandlePair>>& buffers = lock.owns_lock() ? buffers_ : local;
    if (buffers.size() < pieces) buffers.resize(pieces);
    std::vector<std::uint64_t> tests(pieces, 0);
    detail::InOrder joined(pieces + 1);  // the fixed pairs, then every piece
    shares_.run(pieces + 1, [&](unsigned job) {
      if (job == 0) {
        emit_fixed();
      } else {
        // A piece works on a vector and a count on its own stack, moved in
        // and out: the pieces' vector records and counts lie side by side,
        // and writing them on every pair would bounce their cache lines
        // between the cores.
        const unsigned c = job - 1;
        std::vector<HandlePair> buf = std::move(buffers[c]);
        buf.clear();
        auto into = gated<kFiltered>([&buf](Handle a, Handle b) {
          buf.push_back({a, b});
          return true;
        });
        std::uint64_t n_tests = 0;
        find(c, into, n_tests);
        tests[c] = n_tests;
        buffers[c] = std::move(buf);
      }
      joined.finish(job, [&](unsigned piece) {
        if (piece > 0) out.insert(out.end(), buffers[piece - 1].begin(), buffers[piece - 1].end());
      });
    });
    for (unsigned c = 0; c < pieces; ++c) cost.tests += tests[c];
  };

  const std::size_t m = moving_.entries.size();
  const unsigned t = shares_.shares_for(m);
  if (lists_stale_ || (dense_mode_ && t <= 1)) {
    // Rare (a filter changed since the last rebuild), or dense mode on one
    // thread.
    emit_fixed();
    pairs_without_lists(emit_out, cost.tests);
  } else if (t <= 1) {
    emit_fixed();
    mover_pairs(0, m, emit_out, cost.tests);
  } else if (dense_mode_) {
    // The movers' probes of the fixed grid by chunks of the moving grid,
    // then the dense grid's pairs by chunks of its cells.
    const unsigned chunks = t * kChunksPerShare;
    in_pieces(2 * chunks, [&](unsigned c, auto& into, std::uint64_t& tests) {
      if (c < chunks) {
        const auto [begin, end] = slice(m, c, chunks);
        fixed_probes(begin, end, into, tests);
      } else {
        dense_pairs(into, tests, c - chunks, chunks);
      }
    });
  } else {
    const unsigned chunks = t * kChunksPerShare;
    in_pieces(chunks, [&](unsigned c, auto& into, std::uint64_t& tests) {
      const auto [begin, end] = slice(m, c, chunks);
      mover_pairs(begin, end, into, tests);
    });
  }
  loose_pairs(emit_out, cost.tests);
  return cost;
}

std::size_t GridVerlet::memory_bytes() const {
  std::size_t bytes =
      loose_shapes_.capacity() * sizeof(Shape) + user_.capacity() * 8 +
      slots_.capacity() * sizeof(Slot) + loose_.capacity() * 4 +
      loose_bounds_.capacity() * sizeof(AabbF) + loose_speed_.capacity() * 4 +
      held_.capacity() * 4 + fixed_.memory_bytes() + moving_.memory_bytes() +
      fixed_pairs_.capacity() * sizeof(HandlePair) + scratch_items_.capacity() * sizeof(Entry) +
      scratch_src_.capacity() * 4 + scratch_shapes_.capacity() * sizeof(LineShape) +
      moving_scratch_.memory_bytes() + move_target_.capacity() * 4 + lists_.memory_bytes() +
      mark_.capacity() * 4 + (dense_ ? dense_->memory_bytes() : 0) +
      dense_handle_.capacity() * sizeof(Handle) + dense_speed_.capacity() * 4;
  for (const auto& l : dense_later_) bytes += l.capacity() * sizeof(l[0]);
  bytes += dense_grown_.capacity() * sizeof(detail::OccupiedBox);
  std::lock_guard lock(buffers_mutex_);
  for (const auto& b : buffers_) bytes += b.capacity() * sizeof(HandlePair);
  return bytes;
}

void GridVerlet::validate() const {
  const detail::InvariantFailure fail("grid-verlet");
  const std::size_t slots = slots_.size();
  if (user_.size() != slots) fail("slot arrays differ in length");
  std::size_t alive = 0, free = 0, held = 0;
  for (std::size_t s = 0; s < slots; ++s) {
    const bool odd = (slots_[s].gen & 1u) != 0;
    alive += odd;
    if (slots_[s].home == Home::free) ++free;
    if (slots_[s].home == Home::held) ++held;
    if (odd != (slots_[s].home != Home::free && slots_[s].home != Home::held))
      fail("slot " + std::to_string(s) + ": generation and home disagree");
  }
  if (alive != live_) fail("live count");
  if (held != held_.size()) fail("held-back list");
  std::size_t free_list = 0;
  for (std::uint32_t s = free_head_; s != Handle::kNullIndex;
       s = static_cast<std::uint32_t>(user_[s])) {
    if (s >= slots || slots_[s].home != Home::free || ++free_list > slots)
      fail("corrupt free list");
  }
  if (free_list != free) fail("free list misses free slots");
  if (loose_.size() != loose_bounds_.size() || loose_.size() != loose_shapes_.size() ||
      loose_.size() != loose_speed_.size())
    fail("loose arrays differ in length");
  for (std::size_t k = 0; k < loose_.size(); ++k) {
    const std::uint32_t s = loose_[k];
    if (slots_[s].home != Home::loose || slots_[s].pos != k)
      fail("loose list and positions disagree");
    if (slots_[s].motion == Motion::fixed && !fixed_dirty_)
      fail("a fixed loose object without a rebuild due");
    const AabbF b = bounds_f(loose_shapes_[k]);
    if (std::memcmp(&b, &loose_bounds_[k], sizeof b) != 0) fail("stale loose bounds");
  }
  auto check_grid = [&](const Grid& g, Home home, std::size_t expect, const char* name) {
    const std::string gname = name;
    if (g.cell_start.empty() || g.cell_start.back() != g.entries.size() ||
        g.shapes.size() != g.entries.size())
      fail(gname + ": cell index does not cover the entries");
    std::size_t valid = 0;
    for (std::size_t l = 0; l < g.levels.size(); ++l) {
      const Level& lv = g.levels[l];
      const std::uint32_t end_cell = l + 1 < g.levels.size()
                                         ? g.levels[l + 1].first_cell
                                         : static_cast<std::uint32_t>(g.cell_start.size() - 1);
      if (lv.first_cell + lv.cells() != end_cell) fail(gname + ": level cells");
      for (std::uint32_t c = lv.first_cell; c < end_cell; ++c) {
        if (g.cell_start[c] > g.cell_start[c + 1]) fail(gname + ": cell index order");
        for (std::uint32_t k = g.cell_start[c]; k < g.cell_start[c + 1]; ++k) {
          const Entry& e = g.entries[k];
          if (e.slot >= slots) fail(gname + ": slot out of range");
          if (e.dead()) {
            if (slots_[e.slot].home == home && slots_[e.slot].pos == k)
              fail(gname + ": live entry marked dead");
            continue;
          }
          if (slots_[e.slot].home != home || slots_[e.slot].pos != k || slots_[e.slot].gen != e.gen)
            fail(gname + ": entry of an object that left");
          if (!(extent_of(e.lo, e.hi) <= Grid::kFill * lv.reach))
            fail(gname + ": entry on a too small level");
          if (lv.cell_of(e.lo) != c) fail(gname + ": entry in the wrong cell");
          ++valid;
          if (home == Home::moving_grid && dense_mode_) {
            // The entry, its shape and record stay as the last rebuild
            // left them; the dense grid holds the object where it is now.
            const Handle d = dense_handle_[k];
            if (!dense_->contains(d) || dense_->user_data(d) != pack(e.handle()))
              fail(gname + ": a mover missing from the dense grid");
            if (dense_->filter(d) != filter_of(e.slot))
              fail(gname + ": the dense grid's filter differs");
            continue;
          }
          const AabbF b = bounds_f(g.shapes[k]);
          if (home == Home::moving_grid) {
            // Moving entries hold the fat box, around the bounds now.
            const Mover& mv = lists_.movers()[k];
            if (std::memcmp(&b, &mv.cur, sizeof b) != 0) fail(gname + ": stale mover bounds");
            if (std::memcmp(mv.fat.lo, e.lo, sizeof b.lo) != 0 ||
                std::memcmp(mv.fat.hi, e.hi, sizeof b.hi) != 0)
              fail(gname + ": entry is not the mover's fat box");
            if (!mv.fat.contains(b)) fail(gname + ": bounds outside the fat box after a rebuild");
          } else if (std::memcmp(b.lo, e.lo, sizeof b.lo) != 0 ||
                     std::memcmp(b.hi, e.hi, sizeof b.hi) != 0) {
            fail(gname + ": stale entry bounds");
          }
        }
      }
    }
    if (valid != expect) fail(gname + ": live entry count");
  };
  check_grid(fixed_, Home::fixed_grid, fixed_count_, "fixed grid");
  check_grid(moving_, Home::moving_grid, moving_count_, "moving grid");
  if (dense_mode_ != lists_.direct() || dense_mode_ != (dense_ != nullptr))
    fail("dense mode and the movers' lists disagree");
  if (dense_mode_) {
    dense_->validate();
    if (dense_->size() != moving_count_) fail("the dense grid holds other objects than the movers");
  }
  lists_.validate(
      fixed_, moving_, slots,
      [this](std::uint32_t s) -> std::optional<std::uint32_t> {
        if (slots_[s].home != Home::fixed_grid) return std::nullopt;
        return slots_[s].pos;
      },
      filters_, !lists_stale_);
  if (fixed_count_ + moving_count_ + loose_.size() != live_) fail("objects lost between lists");
  if (!cache_built_ && !fixed_pairs_.empty()) fail("a stale pair cache");
  for (const HandlePair& p : fixed_pairs_) {
    const std::uint32_t a = p.a.index, b = p.b.index;
    if (a >= slots || b >= slots || a == b) fail("bad cached pair");
    if (slots_[a].home != Home::fixed_grid || slots_[b].home != Home::fixed_grid) continue;
    if (slots_[a].gen != p.a.generation || slots_[b].gen != p.b.generation)
      fail("cached pair with a stale generation");
    if (!overlaps(shape_of(a), shape_of(b))) fail("cached pair no longer overlaps");
    if (!may_pair(a, b)) fail("cached pair fails the filters");
  }
}

void GridVerlet::visit_cells(CellVisitor visitor) const {
  // Cell (x, y, z) of a level is its (y * n[2] + z) * n[0] + x-th: x runs
  // fastest, so that a row of cells along x is one run of entries.
  int level = 0;
  for (const Grid* g : {&fixed_, &moving_}) {
    if (g == &moving_ && dense_mode_) break;
    for (const Level& lv : g->levels) {
      const int this_level = level++;
      if (!(lv.inv_cell > 0)) continue;  // the unbounded objects' level: no box to show
      const double side = 1 / lv.inv_cell;
      for (std::uint32_t c = 0; c < lv.cells(); ++c) {
        std::size_t held = 0;
        for (std::uint32_t k = g->cell_start[lv.first_cell + c];
             k < g->cell_start[lv.first_cell + c + 1]; ++k)
          held += g->entries[k].dead() ? 0 : 1;
        if (held == 0) continue;
        const std::uint32_t x = c % lv.n[0], z = c / lv.n[0] % lv.n[2], y = c / lv.n[0] / lv.n[2];
        const Vec3 lo{lv.origin[0] + x * side, lv.origin[1] + y * side, lv.origin[2] + z * side};
        visitor(Aabb{lo, {lo.x + side, lo.y + side, lo.z + side}}, this_level, held);
      }
    }
  }
  // The loose objects, in no grid until the next rebuild, and in dense mode
  // the movers (their cells are the dense grid's): each its own box.
  std::vector<AabbF> own = loose_bounds_;
  if (dense_mode_)
    for (std::size_t k = 0; k < moving_.entries.size(); ++k)
      if (!moving_.entries[k].dead()) own.push_back(dense_->bounds_at(dense_handle_[k].index));
  for (const AabbF& b : own) {
    const Aabb box{{b.lo[0], b.lo[1], b.lo[2]}, {b.hi[0], b.hi[1], b.hi[2]}};
    if (std::isfinite(box.lo.x) && std::isfinite(box.lo.y) && std::isfinite(box.lo.z) &&
        std::isfinite(box.hi.x) && std::isfinite(box.hi.y) && std::isfinite(box.hi.z))
      visitor(box, level, 1);
  }
}

}  // namespace broadphase
