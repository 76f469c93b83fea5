#include <broadphase/detail/level_grid.hpp>
#include <cmath>

namespace broadphase::detail {

std::span<const std::uint32_t> LevelGrid::build(std::span<const GridEntry> items,
                                                const LevelGridSpec& spec, const WorkShares& shares,
                                                Scratch& scratch) {
  const std::size_t n = items.size();
  levels.clear();
  cell_start.clear();
  bounded = true;
  // Exact capacities when a grid grows (reserve, unlike resize, does not
  // double): grids are most of the memory held per object.
  // assign, not resize: GCC 12's resize under -fsanitize=undefined reports
  // its own unreachable-point check here (the vectors are sound: ASan is
  // quiet and the release build exact), and assign costs the same fill.
  // Every entry is written by the scatter below and every shape by the
  // caller, so the arrays are filled only when their size changes: a
  // frame's rebuild of the moving grid keeps it, and its fill of 96 bytes
  // an entry ran on one thread (at scaled-even 102 400 it was a tenth of
  // the build on two threads).
  if (entries.size() != n) {
    entries.reserve(n);
    entries.assign(n, GridEntry{});
  }
  if (shapes.size() != n) {
    shapes.reserve(n);
    shapes.assign(n, LineShape{});
  }
  std::vector<std::uint32_t>& tag = scratch.tag;
  std::vector<std::uint32_t>& at = scratch.at;
  tag.resize(n);
  at.resize(n);
  if (n == 0) {
    cell_start.push_back(0);
    return at;
  }
  // The passes over the items are split over the threads, in chunks, each
  // taking a contiguous range and keeping its own totals, merged in chunk
  // order (sums, minima and maxima: the same for any split); the scatter
  // in t shares.
  const unsigned t = shares.shares_for(n);
  const unsigned parts = shares.chunks_for(n);
  std::vector<ShareTotals>& totals = scratch.shares;
  totals.resize(std::max(parts, t));
  shares.run(parts, [&](unsigned k) {
    double m = 0;
    for (auto [i, end] = slice(n, k, parts); i < end; ++i) {
      const double e = extent_of(items[i].lo, items[i].hi);
      if (std::isfinite(e)) m = std::max(m, e);
    }
    totals[k].max_e = m;
  });
  double max_e = 0;
  for (unsigned k = 0; k < parts; ++k) max_e = std::max(max_e, totals[k].max_e);
  // The top level's reach fits the largest finite extent; each level below
  // halves it.
  const double top = max_e > 0 ? max_e / (kFill * kFill) : 1;
  double reach[kLevelSlots];
  for (int k = 0; k < kFiniteLevels; ++k) reach[k] = std::ldexp(top, k - (kFiniteLevels - 1));
  reach[kFiniteLevels] = std::numeric_limits<double>::infinity();

  // Pass 1: each item's level, and each level's count and lower-corner span.
  shares.run(parts, [&](unsigned share) {
    ShareTotals& st = totals[share];
    for (int k = 0; k < kLevelSlots; ++k) {
      st.count[k] = 0;
      std::fill(st.span_lo[k], st.span_lo[k] + 3, std::numeric_limits<float>::infinity());
      std::fill(st.span_hi[k], st.span_hi[k] + 3, -std::numeric_limits<float>::infinity());
      std::fill(st.top[k], st.top[k] + 3, -std::numeric_limits<float>::infinity());
    }
    for (auto [i, end] = slice(n, share, parts); i < end; ++i) {
      const GridEntry& it = items[i];
      const double e = extent_of(it.lo, it.hi);
      int k = kFiniteLevels;
      if (std::isfinite(e)) {
        // Start one below the level log2 suggests, then step up to the fit.
        k = e > 0 ? std::clamp(kFiniteLevels - 2 - std::ilogb(top / e), 0, kFiniteLevels - 1) : 0;
        while (k < kFiniteLevels - 1 && e > kFill * reach[k]) ++k;
      }
      tag[i] = static_cast<std::uint32_t>(k);
      ++st.count[k];
      for (int a = 0; a < 3; ++a) {
        st.span_lo[k][a] = std::min(st.span_lo[k][a], it.lo[a]);
        st.span_hi[k][a] = std::max(st.span_hi[k][a], it.lo[a]);
        st.top[k][a] = std::max(st.top[k][a], it.hi[a]);
      }
    }
  });
  std::uint32_t count[kLevelSlots] = {};
  float span_lo[kLevelSlots][3], span_hi[kLevelSlots][3], upper[kLevelSlots][3];
  for (int k = 0; k < kLevelSlots; ++k) {
    std::fill(span_lo[k], span_lo[k] + 3, std::numeric_limits<float>::infinity());
    std::fill(span_hi[k], span_hi[k] + 3, -std::numeric_limits<float>::infinity());
    std::fill(upper[k], upper[k] + 3, -std::numeric_limits<float>::infinity());
    for (unsigned s = 0; s < parts; ++s) {
      const ShareTotals& st = totals[s];
      count[k] += st.count[k];
      for (int a = 0; a < 3; ++a) {
        span_lo[k][a] = std::min(span_lo[k][a], st.span_lo[k][a]);
        span_hi[k][a] = std::max(span_hi[k][a], st.span_hi[k][a]);
        upper[k][a] = std::max(upper[k][a], st.top[k][a]);
      }
    }
  }
  // A sparse level costs every scan its cell visits but saves few tests:
  // fold it into the level above (its objects fit there too).
  int target[kLevelSlots];
  for (int k = 0; k < kLevelSlots; ++k) target[k] = k;
  for (int k = 0; k + 1 < kFiniteLevels; ++k) {
    if (count[k] == 0 || count[k] * kSparseLevel >= n) continue;
    count[k + 1] += count[k];
    count[k] = 0;
    for (int a = 0; a < 3; ++a) {
      span_lo[k + 1][a] = std::min(span_lo[k + 1][a], span_lo[k][a]);
      span_hi[k + 1][a] = std::max(span_hi[k + 1][a], span_hi[k][a]);
      upper[k + 1][a] = std::max(upper[k + 1][a], upper[k][a]);
    }
    target[k] = k + 1;
  }
  for (int k = kFiniteLevels - 2; k >= 0; --k) target[k] = target[target[k]];
  int level_index[kLevelSlots];
  std::uint32_t cells = 0;
  for (int k = 0; k < kLevelSlots; ++k) {
    level_index[k] = -1;
    if (count[k] == 0) continue;
    GridLevel lv;
    lv.reach = reach[k];
    lv.first_cell = cells;
    for (int a = 0; a < 3; ++a) {
      lv.bound.lo[a] = span_lo[k][a];
      lv.bound.hi[a] = upper[k][a];
    }
    if (std::isfinite(reach[k])) {
      // Cells cover the lower corners of the level's objects inside the
      // world hint; objects beyond it fall into the border cells (the cell
      // function clamps, which keeps every bound conservative).
      double lo[3], span[3];
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::max<double>(span_lo[k][a], spec.world.lo[a]);
        double hi = std::min<double>(span_hi[k][a], spec.world.hi[a]);
        if (hi < lo[a]) {
          lo[a] = span_lo[k][a];
          hi = span_hi[k][a];
        }
        if (!std::isfinite(lo[a]) || !std::isfinite(hi)) lo[a] = hi = 0;
        span[a] = hi - lo[a];
      }
      // One cell side for all axes: the reach times the factor, grown until
      // the cells number at most cells_per_object per object.
      double cell = reach[k] * spec.cell_factor;
      const double budget = std::max(1.0, spec.cells_per_object * count[k]);
      auto cells_for = [&](double c) {
        double total = 1;
        for (int a = 0; a < 3; ++a) total *= std::floor(span[a] / c) + 1;
        return total;
      };
      if (cells_for(cell) > budget) {
        const double widest = std::max({span[0], span[1], span[2]});
        cell = std::max(cell, widest / std::cbrt(budget));
        while (cells_for(cell) > budget) cell *= 1.125;
      }
      lv.inv_cell = 1 / cell;
      for (int a = 0; a < 3; ++a) {
        lv.origin[a] = lo[a];
        lv.n[a] = static_cast<std::uint32_t>(std::floor(span[a] / cell) + 1);
      }
    }
    cells += lv.cells();
    level_index[k] = static_cast<int>(levels.size());
    levels.push_back(lv);
  }
  // Pass 2: counting sort by cell, stable, so entries keep their previous
  // order inside a cell and the result does not depend on anything else.
  // The cells are counted one place up (cell_start[c + 2]), so that after
  // the prefix sum cell_start[c + 1] is the start of cell c: the scatter
  // uses it as the cell's cursor, which leaves it at the start of c + 1.
  shares.run(parts, [&](unsigned share) {
    for (auto [i, end] = slice(n, share, parts); i < end; ++i) {
      const GridLevel& lv = levels[static_cast<std::size_t>(level_index[target[tag[i]]])];
      tag[i] = lv.cell_of(items[i].lo);
    }
  });
  cell_start.assign(cells + 2, 0);
  for (std::size_t i = 0; i < n; ++i) ++cell_start[tag[i] + 2];
  for (std::uint32_t c = 0; c <= cells; ++c) cell_start[c + 1] += cell_start[c];
  // The scatter is split by destination: each share takes the cells of
  // about n/t entries and places, in item order, the items bound for them.
  // Share k takes the cells from its first_cell to the next share's, found
  // before any share moves a cursor.
  const auto starts = cell_start.begin() + 1;  // starts[c]: the start of cell c
  for (unsigned k = 0; k < t; ++k)
    totals[k].first_cell = static_cast<std::uint32_t>(
        std::lower_bound(starts, cell_start.end(), slice(n, k, t).begin) - starts);
  totals[0].first_cell = 0;
  shares.run(t, [&](unsigned share) {
    const std::uint32_t c_lo = totals[share].first_cell;
    const std::uint32_t c_hi = share + 1 < t ? totals[share + 1].first_cell : cells;
    for (std::size_t i = 0; i < n; ++i) {
      if (tag[i] < c_lo || tag[i] >= c_hi) continue;
      const std::uint32_t k = cell_start[tag[i] + 1]++;
      entries[k] = items[i];
      at[i] = k;
    }
  });
  cell_start.pop_back();
  return at;
}

}  // namespace broadphase::detail
