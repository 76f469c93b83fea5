#include <broadphase/fast_grid.hpp>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

namespace broadphase {

namespace {

// Levels halve in reach from the largest finite extent down; twenty finite
// levels span six decades of sizes (smaller objects share the lowest level),
// and one more level of infinite reach takes objects whose float bounds are
// unbounded (centres beyond the float range). Factor 2 keeps an object's
// reach within twice its extent, so a scan window stays tight.
constexpr int kFiniteLevels = 20;
constexpr int kLevelSlots = kFiniteLevels + 1;
// An object goes to a level only when its widest extent is at most this
// fraction of the reach: the 2% margin absorbs the rounding of the cell
// arithmetic, so the row and x-range bounds of a scan stay conservative.
constexpr double kFill = 0.98;
// A level holding less than 1/kSparseLevel of a grid's objects is merged
// into the next larger one.
constexpr std::size_t kSparseLevel = 4;
// Loose and held-back objects tolerated before a mutation rebuilds.
constexpr std::size_t kMinLoose = 64;
// Candidate-list margins: the last displacement times kMarginFrames, at
// least kMinMargin of the object's extent, and at most kMaxMargin of the
// larger of its extent and the fixed grid's finest row cell. The cell term
// lets tiny fast objects keep a list for several frames (rows that fine
// hold few objects), the extent term keeps lists short in dense crowds.
constexpr double kMarginFrames = 8;
constexpr double kMinMargin = 0.02;
constexpr double kMaxMargin = 0.5;
// Moving entries per thread below which find_pairs stays on one thread.
constexpr std::size_t kMinEntriesPerThread = 2048;

double extent_of(const float lo[3], const float hi[3]) {
  double e = 0;
  for (int a = 0; a < 3; ++a)
    e = std::max(e, static_cast<double>(hi[a]) - static_cast<double>(lo[a]));
  return e;
}

}  // namespace

FastGrid::FastGrid(const Config& c) : world_(c.world) {
  OptionReader opt(c, "fast-grid");
  const double t = opt.number("threads", 1, 0, 64);
  cell_factor_ = opt.number("cell", 2, 1, 64);
  opt.finish();
  if (t != std::floor(t)) throw UnknownStructure("fast-grid: option 'threads' must be an integer");
  threads_ = static_cast<unsigned>(t);
  if (threads_ == 0) threads_ = std::max(1u, std::thread::hardware_concurrency());
  if (c.expected_objects > 0) {
    const std::size_t n = c.expected_objects;
    shapes_.reserve(n);
    user_.reserve(n);
    gen_.reserve(n);
    home_.reserve(n);
    motion_.reserve(n);
    loose_pos_.reserve(n);
    list_begin_.reserve(n);
    list_count_.reserve(n);
    list_epoch_.reserve(n);
    fat_.reserve(n);
    speed_.reserve(n);
  }
}

std::uint32_t FastGrid::allocate_slot() {
  std::uint32_t s;
  if (free_head_ != Handle::kNullIndex) {
    s = free_head_;
    free_head_ = static_cast<std::uint32_t>(user_[s]);
  } else {
    if (gen_.size() >= Handle::kNullIndex) throw std::length_error("fast-grid: too many objects");
    s = static_cast<std::uint32_t>(gen_.size());
    shapes_.emplace_back();
    user_.push_back(0);
    gen_.push_back(0);
    home_.push_back(Home::free);
    motion_.push_back(Motion::dynamic);
    loose_pos_.push_back(0);
    list_begin_.push_back(0);
    list_count_.push_back(0);
    list_epoch_.push_back(0);
    fat_.emplace_back();
    speed_.push_back(0);
  }
  ++gen_[s];  // even (free) -> odd (alive)
  ++live_;
  return s;
}

void FastGrid::free_slot(std::uint32_t s) {
  home_[s] = Home::free;
  user_[s] = free_head_;
  free_head_ = s;
}

void FastGrid::add_loose(std::uint32_t s) {
  home_[s] = Home::loose;
  loose_pos_[s] = static_cast<std::uint32_t>(loose_.size());
  loose_.push_back(s);
  loose_bounds_.push_back(bounds_f(shapes_[s]));
}

void FastGrid::drop_loose(std::uint32_t s) {
  const std::uint32_t p = loose_pos_[s];
  const std::uint32_t last = loose_.back();
  loose_[p] = last;
  loose_bounds_[p] = loose_bounds_.back();
  loose_pos_[last] = p;
  loose_.pop_back();
  loose_bounds_.pop_back();
}

void FastGrid::leave_grid(std::uint32_t s) {
  if (home_[s] == Home::fixed_grid) {
    --fixed_count_;
    fixed_dirty_ = true;  // its cached pairs must go at the next rebuild
  } else if (home_[s] == Home::moving_grid) {
    --moving_count_;
  }
}

Handle FastGrid::insert(const Shape& s, std::uint64_t user, Motion m) {
  require_valid(s);
  const std::uint32_t i = allocate_slot();
  shapes_[i] = s;
  user_[i] = user;
  motion_[i] = m;
  add_loose(i);
  if (m == Motion::fixed) fixed_dirty_ = true;
  maybe_rebuild();
  return {i, gen_[i]};
}

void FastGrid::remove(Handle h) {
  const std::uint32_t s = index_of(h);
  ++gen_[s];  // odd -> even: every handle to the object is stale from now on
  --live_;
  if (home_[s] == Home::loose) {
    drop_loose(s);
    free_slot(s);
    return;
  }
  // A grid entry still names this slot: hold the slot back until the grid
  // is rebuilt, so that it cannot be handed to a new object meanwhile.
  leave_grid(s);
  home_[s] = Home::held;
  held_.push_back(s);
  maybe_rebuild();
}

void FastGrid::update(Handle h, const Shape& s) {
  const std::uint32_t i = index_of(h);
  require_valid(s);
  shapes_[i] = s;
  motion_[i] = Motion::dynamic;  // a fixed object that moves is moving from now on
  if (home_[i] == Home::loose) {
    loose_bounds_[loose_pos_[i]] = bounds_f(s);
    return;
  }
  leave_grid(i);
  add_loose(i);
  maybe_rebuild();
}

void FastGrid::update(std::span<const Move> moves) {
  for (const Move& m : moves) {
    index_of(m.handle);
    require_valid(m.shape);
  }
  for (const Move& m : moves) {
    const std::uint32_t i = m.handle.index;
    shapes_[i] = m.shape;
    if (home_[i] == Home::fixed_grid) {
      leave_grid(i);
      motion_[i] = Motion::dynamic;
      add_loose(i);
    } else if (home_[i] == Home::loose) {
      motion_[i] = Motion::dynamic;
      loose_bounds_[loose_pos_[i]] = bounds_f(m.shape);
    } else {
      Entry& e = moving_.entries[loose_pos_[i]];
      const AabbF b = bounds_f(m.shape);
      float d = 0;
      for (int a = 0; a < 3; ++a)
        d = std::max(d, std::max(std::fabs(b.lo[a] - e.lo[a]), std::fabs(b.hi[a] - e.hi[a])));
      speed_[i] = d;
      std::copy(b.lo, b.lo + 3, e.lo);
      std::copy(b.hi, b.hi + 3, e.hi);
    }
  }
  rebuild(fixed_dirty_);
}

void FastGrid::maybe_rebuild() {
  if (loose_.size() + held_.size() > std::max(kMinLoose, live_ / 8)) rebuild(fixed_dirty_);
}

void FastGrid::rebuild(bool fixed_too) {
  auto take_loose = [&](Motion m, std::vector<Entry>& items) {
    for (std::size_t k = 0; k < loose_.size(); ++k) {
      const std::uint32_t s = loose_[k];
      if (motion_[s] != m) continue;
      Entry e{};
      std::copy(loose_bounds_[k].lo, loose_bounds_[k].lo + 3, e.lo);
      std::copy(loose_bounds_[k].hi, loose_bounds_[k].hi + 3, e.hi);
      e.slot = s;
      items.push_back(e);
    }
  };
  if (fixed_too) {
    // The fixed grid is rebuilt rarely: its input is a temporary of the
    // exact size, so the kept scratch array stays as small as the moving set.
    std::vector<Entry> items;
    items.reserve(fixed_count_ + loose_.size());
    for (const Entry& e : fixed_.entries)
      if (home_[e.slot] == Home::fixed_grid) items.push_back(e);
    take_loose(Motion::fixed, items);
    build_grid(fixed_, items);
    for (std::size_t k = 0; k < fixed_.entries.size(); ++k) {
      const std::uint32_t s = fixed_.entries[k].slot;
      home_[s] = Home::fixed_grid;
      loose_pos_[s] = static_cast<std::uint32_t>(k);
    }
    fixed_count_ = fixed_.entries.size();
    build_fixed_cache();
    fixed_dirty_ = false;
    ++epoch_;  // every candidate list names entries of the old fixed grid
  }
  std::vector<Entry>& items = scratch_items_;
  items.clear();
  for (const Entry& e : moving_.entries)
    if (home_[e.slot] == Home::moving_grid) items.push_back(e);
  take_loose(Motion::dynamic, items);
  build_grid(moving_, items);
  for (std::size_t k = 0; k < moving_.entries.size(); ++k) {
    const std::uint32_t s = moving_.entries[k].slot;
    home_[s] = Home::moving_grid;
    loose_pos_[s] = static_cast<std::uint32_t>(k);
  }
  moving_count_ = moving_.entries.size();
  build_candidate_lists();
  loose_.clear();
  loose_bounds_.clear();
  for (std::uint32_t s : held_) free_slot(s);
  held_.clear();
}

bool FastGrid::entry_before(const Entry& x, const Entry& y) {
  return x.lo[0] < y.lo[0] || (x.lo[0] == y.lo[0] && x.slot < y.slot);
}

// Rebuilds take each grid's entries in their previous order, so a row of
// slowly moving objects is nearly sorted: insertion sort finishes it in about
// one pass. A row far from sorted (fresh inserts) falls back to std::sort
// once the shifts exceed a few per entry, which bounds the cost at O(n log n).
void FastGrid::sort_row(Entry* b, Entry* e) {
  const auto n = static_cast<std::size_t>(e - b);
  std::size_t budget = 4 * n + 16;
  for (Entry* p = b + (n > 0 ? 1 : 0); p < e; ++p) {
    if (!entry_before(*p, p[-1])) continue;
    const Entry v = *p;
    Entry* q = p;
    do {
      *q = q[-1];
      --q;
    } while (q != b && entry_before(v, q[-1]) && --budget > 0);
    *q = v;
    if (budget == 0) {
      std::sort(b, e, entry_before);
      return;
    }
  }
}

void FastGrid::build_grid(Grid& g, std::vector<Entry>& items) const {
  const std::size_t n = items.size();
  g.levels.clear();
  g.row_start.clear();
  // Exact capacities when a grid grows (reserve, unlike resize, does not
  // double): grids are most of the memory held per object.
  g.entries.reserve(n);
  g.entry_row.reserve(n);
  g.shapes.reserve(n);
  g.entries.resize(n);
  g.entry_row.resize(n);
  g.shapes.resize(n);
  if (n == 0) {
    g.row_start.push_back(0);
    return;
  }
  // The top level's reach fits the largest finite extent; each level below
  // halves it.
  double max_e = 0;
  for (const Entry& it : items) {
    const double e = extent_of(it.lo, it.hi);
    if (std::isfinite(e)) max_e = std::max(max_e, e);
  }
  const double top = max_e > 0 ? max_e / (kFill * kFill) : 1;
  double reach[kLevelSlots];
  for (int k = 0; k < kFiniteLevels; ++k) reach[k] = std::ldexp(top, k - (kFiniteLevels - 1));
  reach[kFiniteLevels] = std::numeric_limits<double>::infinity();

  // Pass 1: each item's level, and each level's count and lower-corner span.
  std::uint32_t count[kLevelSlots] = {};
  float span_lo[kLevelSlots][2], span_hi[kLevelSlots][2];
  for (int k = 0; k < kLevelSlots; ++k) {
    span_lo[k][0] = span_lo[k][1] = std::numeric_limits<float>::infinity();
    span_hi[k][0] = span_hi[k][1] = -std::numeric_limits<float>::infinity();
  }
  std::vector<std::uint32_t>& tag = g.entry_row;  // level, then row, of each item
  for (std::size_t i = 0; i < n; ++i) {
    const Entry& it = items[i];
    const double e = extent_of(it.lo, it.hi);
    int k = kFiniteLevels;
    if (std::isfinite(e)) {
      // Start one below the level log2 suggests, then step up to the fit.
      k = e > 0 ? std::clamp(kFiniteLevels - 2 - std::ilogb(top / e), 0, kFiniteLevels - 1) : 0;
      while (k < kFiniteLevels - 1 && e > kFill * reach[k]) ++k;
    }
    tag[i] = static_cast<std::uint32_t>(k);
    ++count[k];
    for (int a = 0; a < 2; ++a) {
      span_lo[k][a] = std::min(span_lo[k][a], it.lo[a + 1]);
      span_hi[k][a] = std::max(span_hi[k][a], it.lo[a + 1]);
    }
  }
  // A sparse level costs every scan its row probes but saves few tests:
  // fold it into the level above (its objects fit there too).
  int target[kLevelSlots];
  for (int k = 0; k < kLevelSlots; ++k) target[k] = k;
  for (int k = 0; k + 1 < kFiniteLevels; ++k) {
    if (count[k] == 0 || count[k] * kSparseLevel >= n) continue;
    count[k + 1] += count[k];
    count[k] = 0;
    for (int a = 0; a < 2; ++a) {
      span_lo[k + 1][a] = std::min(span_lo[k + 1][a], span_lo[k][a]);
      span_hi[k + 1][a] = std::max(span_hi[k + 1][a], span_hi[k][a]);
    }
    target[k] = k + 1;
  }
  for (int k = kFiniteLevels - 2; k >= 0; --k) target[k] = target[target[k]];
  int level_index[kLevelSlots];
  std::uint32_t rows = 0;
  for (int k = 0; k < kLevelSlots; ++k) {
    level_index[k] = -1;
    if (count[k] == 0) continue;
    Level lv;
    lv.reach = reach[k];
    lv.first_row = rows;
    // Rows cover the lower corners of the level's objects inside the world
    // hint; objects beyond it fall into the border rows (the cell function
    // clamps, which keeps every bound conservative).
    const auto limit = static_cast<double>(
        std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::sqrt(2.0 * count[k]))));
    double cell = std::isfinite(reach[k]) ? reach[k] * cell_factor_ : 0;
    std::uint32_t n_axis[2] = {1, 1};
    double origin[2] = {0, 0};
    for (int a = 0; a < 2; ++a) {
      double lo = std::max<double>(span_lo[k][a], world_.lo[a + 1]);
      double hi = std::min<double>(span_hi[k][a], world_.hi[a + 1]);
      if (hi < lo) {
        lo = span_lo[k][a];
        hi = span_hi[k][a];
      }
      if (cell > 0 && std::isfinite(lo) && std::isfinite(hi)) {
        origin[a] = lo;
        const double cells = std::floor((hi - lo) / cell) + 1;
        n_axis[a] = static_cast<std::uint32_t>(std::min(cells, limit));
      }
    }
    if (cell > 0) {
      // Both axes share one cell size: the larger of the reach and what the
      // row budget allows on the wider axis.
      for (int a = 0; a < 2; ++a) {
        const double lo = std::max<double>(span_lo[k][a], world_.lo[a + 1]);
        const double hi = std::min<double>(span_hi[k][a], world_.hi[a + 1]);
        if (n_axis[a] == static_cast<std::uint32_t>(limit) && hi > lo)
          cell = std::max(cell, (hi - lo) / limit);
      }
      lv.inv_cell = 1 / cell;
    }
    lv.origin_y = origin[0];
    lv.origin_z = origin[1];
    lv.ny = n_axis[0];
    lv.nz = n_axis[1];
    rows += lv.ny * lv.nz;
    level_index[k] = static_cast<int>(g.levels.size());
    g.levels.push_back(lv);
  }
  // Pass 2: rows, counting sort by row, then each row by lower x.
  g.row_start.assign(rows + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const Level& lv = g.levels[static_cast<std::size_t>(level_index[target[tag[i]]])];
    const Entry& it = items[i];
    const std::uint32_t row = lv.first_row + lv.cell(it.lo[1], lv.origin_y, lv.ny) * lv.nz +
                              lv.cell(it.lo[2], lv.origin_z, lv.nz);
    tag[i] = row;
    ++g.row_start[row + 1];
  }
  for (std::uint32_t r = 0; r < rows; ++r) g.row_start[r + 1] += g.row_start[r];
  // Scatter with row_start as the moving cursor, then shift it back.
  for (std::size_t i = 0; i < n; ++i) g.entries[g.row_start[tag[i]]++] = items[i];
  for (std::uint32_t r = rows; r > 0; --r) g.row_start[r] = g.row_start[r - 1];
  g.row_start[0] = 0;
  for (std::uint32_t r = 0; r < rows; ++r) {
    Entry* b = g.entries.data() + g.row_start[r];
    Entry* e = g.entries.data() + g.row_start[r + 1];
    sort_row(b, e);
    for (Entry* p = b; p != e; ++p) {
      const auto k = static_cast<std::size_t>(p - g.entries.data());
      g.entry_row[k] = r;
      g.shapes[k] = shapes_[p->slot];
    }
  }
}

void FastGrid::build_candidate_lists() {
  const std::size_t m = moving_.entries.size();
  const unsigned t = static_cast<unsigned>(
      std::min<std::size_t>(threads_, std::max<std::size_t>(1, m / kMinEntriesPerThread)));
  list_pool_next_.clear();
  if (t <= 1) {
    build_lists(0, m, list_pool_next_);
  } else {
    // Each thread builds the lists of one contiguous share of the moving
    // entries into its own pool (the lists of distinct slots share no
    // state); the pools are then joined in order, so the lists are the same
    // for every thread count.
    if (list_parts_.size() < t) list_parts_.resize(t);
    {
      std::vector<std::jthread> workers;
      workers.reserve(t - 1);
      for (unsigned k = 1; k < t; ++k)
        workers.emplace_back([this, k, m, t] {
          list_parts_[k].clear();
          build_lists(m * k / t, m * (k + 1) / t, list_parts_[k]);
        });
      build_lists(0, m / t, list_pool_next_);
    }
    for (unsigned k = 1; k < t; ++k) {
      const auto offset = static_cast<std::uint32_t>(list_pool_next_.size());
      for (std::size_t i = m * k / t; i < m * (k + 1) / t; ++i)
        list_begin_[moving_.entries[i].slot] += offset;
      list_pool_next_.insert(list_pool_next_.end(), list_parts_[k].begin(), list_parts_[k].end());
    }
  }
  list_pool_.swap(list_pool_next_);
}

void FastGrid::build_lists(std::size_t begin, std::size_t end, std::vector<std::uint32_t>& pool) {
  const double finest_cell =
      fixed_.levels.empty() || !(fixed_.levels[0].inv_cell > 0) ? 0 : 1 / fixed_.levels[0].inv_cell;
  for (std::size_t i = begin; i < end; ++i) {
    const Entry& e = moving_.entries[i];
    const std::uint32_t s = e.slot;
    const AabbF& fat = fat_[s];
    const std::uint32_t first = static_cast<std::uint32_t>(pool.size());
    const bool inside = list_epoch_[s] == epoch_ && fat.lo[0] <= e.lo[0] && fat.lo[1] <= e.lo[1] &&
                        fat.lo[2] <= e.lo[2] && e.hi[0] <= fat.hi[0] && e.hi[1] <= fat.hi[1] &&
                        e.hi[2] <= fat.hi[2];
    if (inside) {
      // The list covers the object where it is now: keep it.
      const std::uint32_t* old = list_pool_.data() + list_begin_[s];
      pool.insert(pool.end(), old, old + list_count_[s]);
    } else {
      // Grow the bounds by a margin that covers several frames of the last
      // displacement, within the limits above.
      const double extent = extent_of(e.lo, e.hi);
      const double margin =
          std::min(std::max(kMarginFrames * static_cast<double>(speed_[s]), kMinMargin * extent),
                   kMaxMargin * std::max(extent, finest_cell));
      AabbF g;
      for (int a = 0; a < 3; ++a) {
        g.lo[a] = round_down(static_cast<double>(e.lo[a]) - margin);
        g.hi[a] = round_up(static_cast<double>(e.hi[a]) + margin);
      }
      fat_[s] = g;
      list_epoch_[s] = epoch_;
      fixed_.scan(g, 0, kNoMinX, [&](const Entry& o) {
        pool.push_back(static_cast<std::uint32_t>(&o - fixed_.entries.data()));
        return true;
      });
    }
    list_begin_[s] = first;
    list_count_[s] = static_cast<std::uint32_t>(pool.size()) - first;
  }
}

void FastGrid::build_fixed_cache() {
  fixed_pairs_.clear();
  std::uint64_t tests = 0;
  auto emit = [this](std::uint32_t a, std::uint32_t b) {
    fixed_pairs_.push_back({handle_of(a), handle_of(b)});
    return true;
  };
  grid_pairs(fixed_, Home::fixed_grid, 0, fixed_.entries.size(), emit, tests);
  fixed_pairs_.shrink_to_fit();  // the cache is kept until the fixed set changes
}

QueryCost FastGrid::find_pairs(std::vector<HandlePair>& out) const {
  QueryCost cost;
  auto emit_out = [&out, this](std::uint32_t a, std::uint32_t b) {
    out.push_back({handle_of(a), handle_of(b)});
    return true;
  };
  auto emit_cache = [&] {
    if (fixed_count_ == fixed_.entries.size()) {
      // Every cached handle is still current: a fixed object can only change
      // its generation by leaving the grid.
      out.insert(out.end(), fixed_pairs_.begin(), fixed_pairs_.end());
      return;
    }
    out.reserve(out.size() + fixed_pairs_.size());
    for (const HandlePair& p : fixed_pairs_)
      if (home_[p.a.index] == Home::fixed_grid && home_[p.b.index] == Home::fixed_grid)
        out.push_back(p);
  };

  const std::size_t m = moving_.entries.size();
  const unsigned t = static_cast<unsigned>(
      std::min<std::size_t>(threads_, std::max<std::size_t>(1, m / kMinEntriesPerThread)));
  if (t <= 1) {
    emit_cache();
    moving_pairs(0, m, emit_out, cost.tests);
  } else {
    // The workers start first on the later shares, each filling two
    // buffers (pairs from candidate lists, pairs within the moving grid);
    // the main thread meanwhile emits the cache and the first share's list
    // pairs straight into `out`. The buffers are then appended in the order
    // of one thread: all list pairs, then all moving-grid pairs.
    std::unique_lock lock(buffers_mutex_, std::try_to_lock);
    std::vector<std::vector<HandlePair>> local;
    std::vector<std::vector<HandlePair>>& buffers = lock.owns_lock() ? buffers_ : local;
    if (buffers.size() < 2 * t) buffers.resize(2 * t);
    std::vector<std::uint64_t> tests(t, 0);
    auto into = [this](std::vector<HandlePair>& buf) {
      buf.clear();
      return [&buf, this](std::uint32_t a, std::uint32_t b) {
        buf.push_back({handle_of(a), handle_of(b)});
        return true;
      };
    };
    {
      std::vector<std::jthread> workers;
      workers.reserve(t - 1);
      for (unsigned k = 1; k < t; ++k) {
        workers.emplace_back([&, k] {
          const std::size_t begin = m * k / t, end = m * (k + 1) / t;
          auto emit_list = into(buffers[k]);
          list_pairs(begin, end, emit_list, tests[k]);
          auto emit_grid = into(buffers[t + k]);
          grid_pairs(moving_, Home::moving_grid, begin, end, emit_grid, tests[k]);
        });
      }
      emit_cache();
      list_pairs(0, m / t, emit_out, tests[0]);
      auto emit_grid = into(buffers[t]);
      grid_pairs(moving_, Home::moving_grid, 0, m / t, emit_grid, tests[0]);
    }
    for (unsigned k = 0; k < t; ++k) cost.tests += tests[k];
    std::size_t extra = 0;
    for (unsigned k = 1; k < 2 * t; ++k) extra += buffers[k].size();
    out.reserve(out.size() + extra);
    for (unsigned k = 1; k < 2 * t; ++k)
      out.insert(out.end(), buffers[k].begin(), buffers[k].end());
  }
  loose_pairs(emit_out, cost.tests);
  return cost;
}

std::size_t FastGrid::memory_bytes() const {
  std::size_t bytes =
      shapes_.capacity() * sizeof(Shape) + user_.capacity() * 8 + gen_.capacity() * 4 +
      home_.capacity() + motion_.capacity() + loose_pos_.capacity() * 4 + loose_.capacity() * 4 +
      loose_bounds_.capacity() * sizeof(AabbF) + held_.capacity() * 4 + fixed_.memory_bytes() +
      moving_.memory_bytes() + fixed_pairs_.capacity() * sizeof(HandlePair) +
      scratch_items_.capacity() * sizeof(Entry) + fat_.capacity() * sizeof(AabbF) +
      (list_pool_.capacity() + list_pool_next_.capacity() + list_begin_.capacity() +
       list_count_.capacity() + list_epoch_.capacity() + speed_.capacity()) *
          4;
  for (const auto& p : list_parts_) bytes += p.capacity() * 4;
  std::lock_guard lock(buffers_mutex_);
  for (const auto& b : buffers_) bytes += b.capacity() * sizeof(HandlePair);
  return bytes;
}

void FastGrid::validate() const {
  auto fail = [](const std::string& what) { throw std::logic_error("fast-grid: " + what); };
  const std::size_t slots = gen_.size();
  if (shapes_.size() != slots || user_.size() != slots || home_.size() != slots ||
      motion_.size() != slots || loose_pos_.size() != slots)
    fail("slot arrays differ in length");
  std::size_t alive = 0, free = 0, held = 0;
  for (std::size_t s = 0; s < slots; ++s) {
    const bool odd = (gen_[s] & 1u) != 0;
    alive += odd;
    if (home_[s] == Home::free) ++free;
    if (home_[s] == Home::held) ++held;
    if (odd != (home_[s] != Home::free && home_[s] != Home::held))
      fail("slot " + std::to_string(s) + ": generation and home disagree");
  }
  if (alive != live_) fail("live count");
  if (held != held_.size()) fail("held-back list");
  std::size_t free_list = 0;
  for (std::uint32_t s = free_head_; s != Handle::kNullIndex;
       s = static_cast<std::uint32_t>(user_[s])) {
    if (s >= slots || home_[s] != Home::free || ++free_list > slots) fail("corrupt free list");
  }
  if (free_list != free) fail("free list misses free slots");
  if (loose_.size() != loose_bounds_.size()) fail("loose arrays differ in length");
  for (std::size_t k = 0; k < loose_.size(); ++k) {
    const std::uint32_t s = loose_[k];
    if (home_[s] != Home::loose || loose_pos_[s] != k) fail("loose list and positions disagree");
    if (motion_[s] == Motion::fixed && !fixed_dirty_)
      fail("a fixed loose object without a rebuild due");
    const AabbF b = bounds_f(shapes_[s]);
    if (std::memcmp(&b, &loose_bounds_[k], sizeof b) != 0) fail("stale loose bounds");
  }
  auto check_grid = [&](const Grid& g, Home home, std::size_t expect, const char* name) {
    const std::string gname = name;
    if (g.row_start.empty() || g.row_start.back() != g.entries.size())
      fail(gname + ": row index does not cover the entries");
    std::size_t valid = 0;
    for (std::size_t l = 0; l < g.levels.size(); ++l) {
      const Level& lv = g.levels[l];
      const std::uint32_t end_row = l + 1 < g.levels.size()
                                        ? g.levels[l + 1].first_row
                                        : static_cast<std::uint32_t>(g.row_start.size() - 1);
      if (lv.first_row + lv.ny * lv.nz != end_row) fail(gname + ": level rows");
      for (std::uint32_t r = lv.first_row; r < end_row; ++r) {
        for (std::uint32_t k = g.row_start[r]; k < g.row_start[r + 1]; ++k) {
          const Entry& e = g.entries[k];
          if (g.entry_row[k] != r) fail(gname + ": entry row");
          if (k > g.row_start[r] && g.entries[k - 1].lo[0] > e.lo[0]) fail(gname + ": row order");
          if (!(extent_of(e.lo, e.hi) <= kFill * lv.reach))
            fail(gname + ": entry on a too small level");
          const std::uint32_t row = lv.first_row + lv.cell(e.lo[1], lv.origin_y, lv.ny) * lv.nz +
                                    lv.cell(e.lo[2], lv.origin_z, lv.nz);
          if (row != r) fail(gname + ": entry in the wrong row");
          if (e.slot >= slots) fail(gname + ": slot out of range");
          if (home_[e.slot] != home) continue;
          ++valid;
          if (loose_pos_[e.slot] != k) fail(gname + ": slot position");
          if (!(g.shapes[k] == shapes_[e.slot])) fail(gname + ": stale shape copy");
          const AabbF b = bounds_f(shapes_[e.slot]);
          if (std::memcmp(b.lo, e.lo, sizeof b.lo) != 0 ||
              std::memcmp(b.hi, e.hi, sizeof b.hi) != 0)
            fail(gname + ": stale entry bounds");
        }
      }
    }
    if (valid != expect) fail(gname + ": live entry count");
  };
  check_grid(fixed_, Home::fixed_grid, fixed_count_, "fixed grid");
  check_grid(moving_, Home::moving_grid, moving_count_, "moving grid");
  if (fixed_count_ + moving_count_ + loose_.size() != live_) fail("objects lost between lists");
  for (const HandlePair& p : fixed_pairs_) {
    const std::uint32_t a = p.a.index, b = p.b.index;
    if (a >= slots || b >= slots || a == b) fail("bad cached pair");
    if (home_[a] != Home::fixed_grid || home_[b] != Home::fixed_grid) continue;
    if (gen_[a] != p.a.generation || gen_[b] != p.b.generation)
      fail("cached pair with a stale generation");
    if (!overlaps(shapes_[a], shapes_[b])) fail("cached pair no longer overlaps");
  }
}

}  // namespace broadphase
