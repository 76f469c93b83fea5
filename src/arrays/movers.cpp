// The tracker's movers mode (movers.hpp): the quiet spheres in the sphere
// kernel's grids with their pairs, the movers' pairs found afresh on every
// call, and its invariants; then the tracker's ways into it.
#include "movers.hpp"

#include <algorithm>
#include <bit>
#include <broadphase/detail/sort_keys.hpp>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_set>

#include "pair_tracker_impl.hpp"

namespace broadphase::arrays::detail {

namespace {

// A list longer than this is not kept (the mover probes on every call).
constexpr std::size_t kMaxListLength = 0xFFFF;
// How many movers ahead a list's header is asked for (its entries half as
// far ahead).
constexpr std::size_t kListPrefetch = 16;
// A mover whose list was too long, or did not fit the lists' memory, has
// reach kNoRoom; it probes with its own radius for kNoRoomCalls calls
// before it tries to make a list again (else every call would probe with
// the list's reach, gather, and throw the list away).
constexpr float kNoRoom = -2;
constexpr std::uint16_t kNoRoomCalls = 16;
constexpr std::size_t kFarRecords = std::size_t{16} << 20;  // bytes
// How many movers ahead the gather in the quiet cells' order asks for a
// mover's values.
constexpr std::size_t kReadPrefetch = 16;

// Cells over the spheres `subset` of `o` (all of them when empty) with one
// cell a sphere (kCoarseCellsPerObject), where their radii span more than a
// factor kCoarseSpread and they are then no more crowded than
// kCoarseCrowd; false otherwise, with `cells` empty. Spheres of about one
// size keep the kernel's cells, as fine as their diameter.
bool build_coarse_cells(detail::SphereCells& cells, const Objects& o,
                        std::span<const std::uint32_t> subset) {
  if (o.radius.empty()) return false;  // (boxes only)
  double rmin = HUGE_VAL, rmax = 0;
  const std::size_t n = subset.empty() ? o.count : subset.size();
  for (std::size_t k = 0; k < n; ++k) {
    const double r = o.radius.at(subset.empty() ? k : subset[k]);
    rmin = std::min(rmin, r);
    rmax = std::max(rmax, r);
  }
  if (!(rmax > kCoarseSpread * rmin)) return false;
  const bool built = subset.empty() ? cells.build(o, kCoarseCellsPerObject)
                                    : cells.build(o, subset, kCoarseCellsPerObject);
  if (built && cells.crowd() <= kCoarseCrowd) return true;
  cells = detail::SphereCells{};
  return false;
}

}  // namespace

bool build_quiet_cells(detail::SphereCells& cells, const Objects& o,
                       std::span<const std::uint32_t> still) {
  if (build_coarse_cells(cells, o, still)) return true;
  const bool built = still.empty() ? cells.build(o) : cells.build(o, still);
  return built && cells.crowd() <= kMoversCrowd;
}

// Its distance from the list's centre plus its radius at most the reach,
// less a margin far above the rounding of this test, of the predicate and of
// the probe that made the list (relative 2^-40 of the magnitudes involved,
// against errors of a few 2^-53). Inlined into the movers' loop: GCC kept
// it out of line, 5% of a call at study even 6 400. With the list's pairs
// written in place (below), alternated on one core: study even 6 400
// 0.231-0.235 -> 0.227-0.230 ms, scaled-even 1 024 000 75.0-75.4 -> 72.6-73.6.
[[gnu::always_inline]] inline bool MoverList::holds(double x, double y, double z, double r,
                                                    double quiet_rmax) const {
  if (!(reach >= 0)) return false;
  const double dx = x - static_cast<double>(cx), dy = y - static_cast<double>(cy),
               dz = z - static_cast<double>(cz);
  const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
  const double slack = (std::abs(x) + std::abs(y) + std::abs(z) + reach + quiet_rmax) * 0x1p-40;
  return d * (1 + 0x1p-40) + r <= static_cast<double>(reach) - slack;
}

namespace {

// v rounded up to a float.
float float_up(double v) {
  auto f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, HUGE_VALF);
  return f;
}

}  // namespace

// Reaching the mover's radius plus a skin of kListSkinCalls calls at the
// speed it went with since the last list, at least kListSkinShare of its
// radius, at most four radii plus kListSkinQuiet of the largest quiet
// radius, and far above the centre's rounding (2^-20 of its coordinates
// against 2^-24). The centre (rounded to float) is put ahead of the mover
// along the way it went, by kListAhead times the skin beyond
// kListSkinShare of its radius, at most the skin less 2^-10 of it: a mover
// in steady motion then crosses the whole list before it renews it, not
// half of it (see kListAhead). The speed counts how far the last centre
// was put ahead (the same rule, from its reach). Where the list would not
// hold the mover by MoverList::holds (a margin of 2^-40 of magnitudes far
// larger than the skin), it is centred on the mover, which it then holds.
// reach < 0 where a float cannot hold it.
MoverList MoverList::next(double x, double y, double z, double r, std::uint16_t now,
                          double quiet_rmax) const {
  const MoverList& old = *this;
  MoverList l;
  const double least = kListSkinShare * r;
  auto ahead_of = [&](double skin) {
    return std::min(kListAhead * std::max(0.0, skin - least), skin * (1 - 0x1p-10));
  };
  double skin = least;
  double way[3] = {0, 0, 0};  // from the last centre to the mover
  double went = 0;
  if (old.reach >= 0) {
    const auto calls = static_cast<std::uint16_t>(now - old.stamp);
    way[0] = x - static_cast<double>(old.cx);
    way[1] = y - static_cast<double>(old.cy);
    way[2] = z - static_cast<double>(old.cz);
    went = std::sqrt(way[0] * way[0] + way[1] * way[1] + way[2] * way[2]);
    if (calls > 0)
      skin = std::max(
          skin,
          std::min(4 * r + kListSkinQuiet * quiet_rmax,
                   kListSkinCalls * (went + ahead_of(static_cast<double>(old.reach) - r)) / calls));
  }
  double c[3] = {x, y, z};
  if (went > 0 && std::isfinite(went)) {
    const double step = ahead_of(skin) / went;
    for (int a = 0; a < 3; ++a) c[a] += way[a] * step;
  }
  skin += (std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2])) * 0x1p-20;
  l.stamp = now;
  // (A double past the floats' range does not convert: no list then.)
  constexpr double kFloatMax = 0x1p127;
  if (!(std::abs(x) < kFloatMax && std::abs(y) < kFloatMax && std::abs(z) < kFloatMax &&
        std::abs(c[0]) < kFloatMax && std::abs(c[1]) < kFloatMax && std::abs(c[2]) < kFloatMax &&
        r + skin < kFloatMax))
    return l;  // reach < 0
  l.cx = static_cast<float>(c[0]);
  l.cy = static_cast<float>(c[1]);
  l.cz = static_cast<float>(c[2]);
  l.reach = float_up(r + skin);
  if (!l.holds(x, y, z, r, quiet_rmax)) {
    l.cx = static_cast<float>(x);
    l.cy = static_cast<float>(y);
    l.cz = static_cast<float>(z);
  }
  return l;
}

bool Movers::stale(const QuietSet& quiet, const std::vector<std::uint64_t>& changed,
                   std::size_t changed_count) const {
  std::size_t waking = 0;
  for (std::size_t w = 0; w < changed.size(); ++w)
    waking += static_cast<std::size_t>(std::popcount(changed[w] & quiet.bits[w]));
  return (woken.size() + waking) * kWokenShare > quiet_at_partition ||
         (calls >= kMoversPatience && active.size() + woken.size() > 2 * changed_count + 64);
}

ArrayCallStats Movers::call(const Objects& o, const std::vector<std::uint64_t>& changed,
                            const PairSink& sink, bool check_listed, QuietSet& quiet,
                            const ArrayOptions& options) {
  ArrayCallStats stats;
  stats.movers = true;
  // The quiet objects listed wake: their records in `quiet_cells` are stale
  // from then on (a probe skips them), and so are their quiet pairs. They
  // are found first, and woken once the values are read and checked.
  std::vector<std::uint32_t> waking;
  for (std::size_t w = 0; w < changed.size(); ++w)
    for (std::uint64_t b = changed[w] & quiet.bits[w]; b != 0; b &= b - 1)
      waking.push_back(
          static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b))));
  const std::size_t m = active.size() + woken.size() + waking.size();
  // The movers' shapes, read from the caller's columns in increasing index
  // (the active ones are: a stream rather than a miss per value) and
  // widened exactly to double, then put in the order of the quiet cells'
  // finest grid, so that one probe reads much of what the last one read.
  struct Read {
    double x, y, z, r;
  };
  // Per-call arrays in BigVectors: not zeroed, and their blocks kept for
  // the next call (big_blocks.cpp); the gather below asks for a mover's
  // values ahead (perf at 10 240 000 put 4% of a call on that load, a
  // cache miss a mover). Alternated on one core: 10 240 000, 12 calls,
  // 913-928 -> 845-864 ms median; the million 1-2% faster.
  BigVector<Read> read(m);
  BigVector<std::uint64_t> keyed(m);
  // With `check_listed`, the values of the objects listed are checked as
  // they are read (every one of them is a mover by now), rather than in a
  // pass of their own over the caller's columns before: at scaled-even
  // 1 024 000 that pass read 32 MB for 2-3 ms of a 65 ms call. A bad one
  // throws from check_listed, which names the first, before
  // anything changes.
  bool bad = check_listed && (o.x.empty() || o.y.empty() || o.z.empty() || o.radius.empty());
  if (!bad) {
    auto take = [&](std::size_t k, std::uint32_t i) {
      const double x = o.x.at(i), y = o.y.at(i), z = o.z.at(i), r = o.radius.at(i);
      read[k] = {x, y, z, r};
      if (check_listed)
        bad |= !(std::isfinite(x) && std::isfinite(y) && std::isfinite(z) && std::isfinite(r) &&
                 r >= 0) &&
               test_bit(changed, i);
      keyed[k] = (static_cast<std::uint64_t>(quiet_cells.cell_key(x, y, z)) << 32) | k;
    };
    std::size_t k = 0;
    for (const std::uint32_t i : active) take(k++, i);
    for (const std::uint32_t i : woken) take(k++, i);
    for (const std::uint32_t i : waking) take(k++, i);
  }
  if (bad) detail::check_listed(o, changed);
  ++calls;
  for (const std::uint32_t i : waking) {
    quiet.wake(i);
    woken.push_back(i);
  }
  stats.woken = waking.size();
  stats.quiet = quiet.count;
  auto mover = [&](std::size_t k) {
    return k < active.size() ? active[k] : woken[k - active.size()];
  };
  broadphase::detail::sort_by_high_word(keyed);
  // Lists for every mover where the quiet pairs are few (fewer than two
  // an object). In denser sets a list holds tens of candidates: there
  // the lists together take at most half of ArrayOptions::spare_bytes
  // (their headers at most a quarter of that, else there are none), and
  // a mover whose list finds no room probes. At scaled-uneven 1 024 000,
  // lists for all took the own memory from 84 to 163 B/object (the lean
  // path promises 100) for a call 264 -> 182 ms; at study uneven 6 400
  // they take 200 KB, and the call went from 0.96 to 0.58 ms; at
  // scaled-uneven 102 400, 7 MB: 24 -> 16-17 ms.
  const bool dense = quiet.hits.many(o.count);
  const std::size_t list_bytes = spare_half(options);
  constexpr std::size_t kHeader = sizeof(MoverList) + sizeof(std::uint32_t);  // and list_of
  const bool lists = !dense || m * kHeader <= list_bytes / 4;
  // (Half the rest for the pool's entries: its capacity may double.)
  const std::size_t pool_room = !dense || !lists
                                    ? std::numeric_limits<std::size_t>::max()
                                    : (list_bytes - m * kHeader) / 2 / sizeof(std::uint32_t);
  // (New slots get new lists at the end: list_of stays a permutation.)
  if (lists && list_of.size() < m) {
    const std::size_t had = list_of.size();
    list_of.resize(m);
    mover_lists.resize(m);
    for (std::size_t k = had; k < m; ++k) list_of[k] = static_cast<std::uint32_t>(k);
  }
  BigVector<std::uint32_t> ids(m);
  BigVector<double> xyzr(4 * m);
  BigVector<std::uint32_t> lst(lists ? m : 0);  // the k-th mover's list
  for (std::size_t k = 0; k < m; ++k) {
    if (k + kReadPrefetch < m)
      __builtin_prefetch(&read[static_cast<std::uint32_t>(keyed[k + kReadPrefetch])]);
    const auto from = static_cast<std::uint32_t>(keyed[k]);
    ids[k] = mover(from);
    if (lists) lst[k] = list_of[from];
    xyzr[4 * k] = read[from].x;
    xyzr[4 * k + 1] = read[from].y;
    xyzr[4 * k + 2] = read[from].z;
    xyzr[4 * k + 3] = read[from].r;
  }
  Emitter emit(sink, options.sorted, stats, PairFilterColumns::of(o));
  const unsigned threads = thread_count(options.threads);
  // The quiet pairs as they stand (without those of woken objects).
  bool go_on = quiet.deliver(emit, threads, !woken.empty());
  // The movers among themselves: the one-shot call.
  if (go_on && !emit.stopped()) {
    Objects view;
    view.count = m;
    const auto stride = static_cast<std::ptrdiff_t>(4 * sizeof(double));
    view.x = {xyzr.data(), stride, Real::f64};
    view.y = {xyzr.data() + 1, stride, Real::f64};
    view.z = {xyzr.data() + 2, stride, Real::f64};
    view.radius = {xyzr.data() + 3, stride, Real::f64};
    ArrayOptions one = options;
    one.sorted = false;
    std::vector<IndexPair> among;
    detail::SphereCells cells;
    if (build_coarse_cells(cells, view, {})) {
      cells.add_columns();  // scanned once: from columns (see scan_columns)
      stats.tests += cell_pairs(cells, append_to(among), one).tests;
    } else
      stats.tests += broadphase::find_pairs(view, among, one).tests;
    for (IndexPair& p : among) p = ordered(ids[p.i], ids[p.j]);
    go_on = emit.deliver_slices(among);
  }
  // The movers with the quiet: each tests its list of quiet candidates
  // while it holds, else probes the quiet grids for a new one.
  if (go_on && !emit.stopped()) {
    const auto now = static_cast<std::uint16_t>(calls);
    const double quiet_rmax = quiet_cells.max_radius();
    // (Woken objects' records are stale: skipped, when there are any.)
    const bool any_woken = quiet_cells.size() != quiet.count;
    struct Renewal {
      std::uint32_t index;  // of its mover's list in mover_lists
      MoverList list;
      std::size_t at;  // its records in the chunk's `records`
    };
    struct Chunk {
      BigVector<IndexPair> pairs;  // (grown without zeroing)
      std::uint64_t tests = 0;
      std::vector<Renewal> renewals;
      std::vector<std::uint32_t> records;
    };
    std::vector<Renewal> renewals;
    std::vector<std::uint32_t> records;
    run_in_order<Chunk>(
        m, threads,
        [&](std::size_t begin, std::size_t end, Chunk& out) {
          out.pairs.clear();
          out.tests = 0;
          out.renewals.clear();
          out.records.clear();
          // Where the quiet records are far larger than the caches, the
          // records of a list too are asked for ahead, once its entries
          // are in: at scaled-even 1 024 000 (29 MB of records), over eight
          // alternated runs of 40 calls, medians 69.5-73.6 ms against
          // 70.8-75.7, means 73.0-77.0 against 75.5-81.7; at 6 400 and
          // 102 400, where the records fit, it cost 3-7%.
          const bool far_records = quiet_cells.memory_bytes() >= kFarRecords;
          for (std::size_t k = begin; k < end; ++k) {
            // The movers come in the quiet cells' order, their lists in
            // that of the last call (see list_of): mostly in sequence, but
            // asked for ahead all the same, and the list's entries once
            // its header is in (in slot order, without, the test of
            // whether a list holds took 10% of a call at scaled-even
            // 1 024 000).
            if (lists) {
              if (k + kListPrefetch < end) __builtin_prefetch(&mover_lists[lst[k + kListPrefetch]]);
              if (k + kListPrefetch / 2 < end) {
                const MoverList& ahead = mover_lists[lst[k + kListPrefetch / 2]];
                if (ahead.len > 0) __builtin_prefetch(&list_pool[ahead.first]);
              }
              if (far_records && k + kListPrefetch / 4 < end) {
                const MoverList& ahead = mover_lists[lst[k + kListPrefetch / 4]];
                for (std::uint32_t e = 0; e < ahead.len; ++e)
                  quiet_cells.prefetch_record(list_pool[ahead.first + e]);
              }
            }
            const std::uint32_t i = ids[k];
            const std::uint32_t held_at = lists ? lst[k] : 0;
            const double x = xyzr[4 * k], y = xyzr[4 * k + 1], z = xyzr[4 * k + 2],
                         r = xyzr[4 * k + 3];
            // A quiet sphere found overlapping (a probe tests it), and one
            // from a list, tested here.
            auto keeps = [&](std::uint32_t j) { return !any_woken || quiet.has(j); };
            auto hit = [&](std::uint32_t q) {
              const std::uint32_t j = quiet_cells.record_id(q);
              if (keeps(j)) out.pairs.push_back(ordered(i, j));
            };
            // A list's pairs are written in place, at most one a candidate,
            // without a check of the vector's room for each.
            auto test = [&](std::span<const std::uint32_t> listed) {
              const std::size_t at = out.pairs.size();
              out.pairs.resize(at + listed.size());
              IndexPair* w = out.pairs.data() + at;
              quiet_cells.test_records(listed, x, y, z, r, [&](std::uint32_t q) {
                const std::uint32_t j = quiet_cells.record_id(q);
                *w = ordered(i, j);
                w += keeps(j);
              });
              out.pairs.resize(static_cast<std::size_t>(w - out.pairs.data()));
            };
            if (!lists) {
              out.tests += quiet_cells.probe_records(x, y, z, r, hit);
              continue;
            }
            const MoverList& held = mover_lists[held_at];
            if (held.holds(x, y, z, r, quiet_rmax)) {
              out.tests += held.len;
              test(std::span<const std::uint32_t>(list_pool).subspan(held.first, held.len));
              continue;
            }
            if (held.reach == kNoRoom &&
                static_cast<std::uint16_t>(now - held.stamp) < kNoRoomCalls) {
              out.tests += quiet_cells.probe_records(x, y, z, r, hit);
              continue;
            }
            const MoverList next = held.next(x, y, z, r, now, quiet_rmax);
            if (next.reach < 0) {  // no list: a probe
              out.tests += quiet_cells.probe_records(x, y, z, r, hit);
              out.renewals.push_back({held_at, next, out.records.size()});
              continue;
            }
            const std::size_t at = out.records.size();
            out.tests +=
                quiet_cells.probe_records(next.cx, next.cy, next.cz, next.reach,
                                          [&](std::uint32_t q) { out.records.push_back(q); });
            out.tests += out.records.size() - at;
            test(std::span<const std::uint32_t>(out.records).subspan(at));
            Renewal renewal{held_at, next, at};
            if (out.records.size() - at > kMaxListLength) {
              renewal.list.reach = kNoRoom;
              out.records.resize(at);
            }
            renewal.list.len = static_cast<std::uint16_t>(out.records.size() - at);
            out.renewals.push_back(renewal);
          }
        },
        [&](Chunk& c) {
          stats.tests += c.tests;
          for (Renewal& rn : c.renewals) {
            rn.at += records.size();
            renewals.push_back(rn);
          }
          records.insert(records.end(), c.records.begin(), c.records.end());
          return emit.deliver(std::span<const IndexPair>(c.pairs));
        });
    // The new lists, in place of the old ones where they fit, else at the
    // end of the pool, which is compacted once a fifth of it is dead.
    stats.renewed = renewals.size();
    for (const Renewal& rn : renewals) {
      MoverList& held = mover_lists[rn.index];
      MoverList next = rn.list;
      list_pool_live -= held.len;
      if (next.len > held.len && list_pool.size() + next.len > pool_room) {
        next.reach = kNoRoom;
        next.len = 0;
      }
      if (next.len > held.len) {
        next.first = static_cast<std::uint32_t>(list_pool.size());
        list_pool.insert(list_pool.end(), records.begin() + static_cast<std::ptrdiff_t>(rn.at),
                         records.begin() + static_cast<std::ptrdiff_t>(rn.at + next.len));
      } else {
        next.first = held.first;
        std::copy_n(records.begin() + static_cast<std::ptrdiff_t>(rn.at), next.len,
                    list_pool.begin() + held.first);
      }
      list_pool_live += next.len;
      held = next;
    }
    // The lists in this call's order, for the next call.
    if (lists) {
      BigVector<MoverList> placed(m);
      for (std::size_t k = 0; k < m; ++k) {
        placed[k] = mover_lists[lst[k]];
        list_of[static_cast<std::uint32_t>(keyed[k])] = static_cast<std::uint32_t>(k);
      }
      mover_lists = std::move(placed);
    }
    if (list_pool.size() > list_pool_live + list_pool_live / 4 + 4096) {
      BigVector<std::uint32_t> pool;
      pool.reserve(list_pool_live);
      for (MoverList& l : mover_lists) {
        const std::uint32_t first = l.first;
        l.first = static_cast<std::uint32_t>(pool.size());
        pool.insert(pool.end(), list_pool.begin() + first, list_pool.begin() + first + l.len);
      }
      list_pool = std::move(pool);
    }
  }
  emit.finish();
  return stats;
}

// The movers mode's invariants (see PairTracker::Impl::movers).
std::size_t Movers::memory_bytes() const {
  return quiet_cells.memory_bytes() +
         (active.capacity() + woken.capacity() + list_pool.capacity() + list_of.capacity()) *
             sizeof(std::uint32_t) +
         mover_lists.capacity() * sizeof(MoverList);
}

void Movers::check(const Objects& objects, const QuietSet& quiet) const {
  const Movers& im = *this;
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  const std::size_t n = objects.count;
  if (quiet.bits.size() != (n + 63) / 64) fail("one quiet bit per object");
  // Every object is exactly one of quiet, active (increasing) and woken.
  enum : char { kNone, kQuiet, kActive, kWoken };
  std::vector<char> role(n, kNone);
  std::size_t quiet_seen = 0;
  for (std::uint32_t i = 0; i < n; ++i)
    if (quiet.has(i)) {
      role[i] = kQuiet;
      ++quiet_seen;
    }
  if (quiet_seen != quiet.count) fail("quiet bits and count disagree");
  for (std::size_t k = 0; k < im.active.size(); ++k) {
    const std::uint32_t i = im.active[k];
    if (i >= n || role[i] != kNone || (k > 0 && im.active[k - 1] >= i))
      fail("active object " + std::to_string(i) + " out of range, order or also quiet");
    role[i] = kActive;
  }
  for (std::uint32_t i : im.woken) {
    if (i >= n || role[i] != kNone) fail("woken object " + std::to_string(i) + " listed wrongly");
    role[i] = kWoken;
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    if (role[i] == kNone) fail("object " + std::to_string(i) + " is neither quiet nor a mover");
    if (!objects.is_sphere(i)) fail("object " + std::to_string(i) + " is not a sphere");
  }
  // The quiet cells hold every quiet and woken object once, and no other,
  // the quiet ones exactly as they are now.
  im.quiet_cells.validate();
  std::vector<char> held(n, 0);
  im.quiet_cells.for_each([&](std::uint32_t i, double x, double y, double z, double r) {
    if (i >= n || held[i] || role[i] == kActive)
      fail("quiet cells hold " + std::to_string(i) + " wrongly or twice");
    held[i] = 1;
    if (role[i] == kQuiet && (x != objects.x.at(i) || y != objects.y.at(i) ||
                              z != objects.z.at(i) || r != objects.radius.at(i)))
      fail("quiet object " + std::to_string(i) + " changed without being listed");
  });
  for (std::uint32_t i = 0; i < n; ++i)
    if (role[i] != kActive && !held[i])
      fail("quiet object " + std::to_string(i) + " is not in the quiet cells");
  // The quiet pairs: each once, i < j, of two objects quiet at the
  // partition, overlapping while both still are; all of them on small sets.
  std::unordered_set<std::uint64_t> seen;
  quiet.hits.for_each([&](const IndexPair& q) {
    const std::string name =
        "quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) + ")";
    if (q.i >= q.j || q.j >= n) fail(name + " out of order or range");
    if (role[q.i] == kActive || role[q.j] == kActive) fail(name + " has a mover");
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second) fail(name + " listed twice");
    if (role[q.i] == kQuiet && role[q.j] == kQuiet &&
        !overlaps(objects.shape(q.i), objects.shape(q.j)))
      fail(name + " does not overlap");
  });
  if (n <= 3000)
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (role[i] == kQuiet && role[j] == kQuiet &&
            overlaps(objects.shape(i), objects.shape(j)) &&
            !seen.count((std::uint64_t(i) << 32) | j))
          fail("overlapping quiet objects " + std::to_string(i) + " and " + std::to_string(j) +
               " are not a quiet pair");
  // The movers' lists: within the pool, live entries counted, each exactly
  // the quiet records a probe of its centre and reach finds (on sets small
  // enough to probe once a list).
  if (im.mover_lists.size() > im.active.size() + im.woken.size())
    fail("more movers' lists than movers");
  if (im.list_of.size() != im.mover_lists.size())
    fail("list_of has " + std::to_string(im.list_of.size()) + " entries for " +
         std::to_string(im.mover_lists.size()) + " lists");
  {
    std::vector<char> taken(im.list_of.size(), 0);
    for (std::size_t k = 0; k < im.list_of.size(); ++k) {
      const std::uint32_t l = im.list_of[k];
      if (l >= taken.size() || taken[l]++ != 0)
        fail("slot " + std::to_string(k) + "'s list " + std::to_string(l) +
             " is out of range or another slot's");
    }
  }
  std::size_t live = 0;
  for (std::size_t k = 0; k < im.mover_lists.size(); ++k) {
    const MoverList& l = im.mover_lists[k];
    const std::string name = "mover list " + std::to_string(k);
    if (!(l.reach >= 0)) {
      if (l.len != 0) fail(name + " has no reach but entries");
      continue;
    }
    live += l.len;
    if (std::size_t{l.first} + l.len > im.list_pool.size()) fail(name + " is outside the pool");
    if (n > 20000) continue;
    std::vector<std::uint32_t> want,
        got(im.list_pool.begin() + l.first, im.list_pool.begin() + l.first + l.len);
    im.quiet_cells.probe_records(l.cx, l.cy, l.cz, l.reach,
                                 [&](std::uint32_t q) { want.push_back(q); });
    if (got != want)
      fail(name + " holds " + std::to_string(got.size()) + " records, its probe finds " +
           std::to_string(want.size()));
  }
  if (live != im.list_pool_live) fail("the movers' lists' live entries miscounted");
}

}  // namespace broadphase::arrays::detail

namespace broadphase::arrays {

bool PairTracker::Impl::enter_movers(const Objects& o, const std::vector<std::uint64_t>& changed) {
  // The cheap refusals first: the index tries this on every call while it
  // has quiet objects.
  const auto n = static_cast<std::uint32_t>(o.count);
  if (o.radius.empty()) return false;
  std::size_t listed = 0;
  for (const std::uint64_t w : changed) listed += static_cast<std::size_t>(std::popcount(w));
  if (listed * kMoversShare > n) return false;
  if (o.kind != nullptr) {
    if (last_box < n && !o.is_sphere(last_box)) return false;  // still a box
    for (std::uint32_t i = 0; i < n; ++i)
      if (!o.is_sphere(i)) {
        last_box = i;
        return false;
      }
  }
  std::vector<std::uint32_t> still, moving;
  for (std::uint32_t i = 0; i < n; ++i) (test_bit(changed, i) ? moving : still).push_back(i);
  detail::SphereCells cells;
  if (!build_quiet_cells(cells, o, still)) {
    movers_refused = true;  // not tried again before a rebuild: a build is dear
    return false;
  }
  std::vector<IndexPair> hits;
  ArrayOptions unsorted = options;
  unsorted.sorted = false;
  cell_pairs(cells, append_to(hits), unsorted);
  // The index and everything else go: a tracker as new, but for the
  // options and the quiet set's pace.
  Impl next;
  next.options = options;
  next.quiet.after = quiet.after;
  next.quiet.listed_calls = quiet.listed_calls;
  next.count = n;
  next.mode = Mode::movers;
  next.movers.quiet_cells = std::move(cells);
  next.quiet.hits.assign(hits, n, spare_half(options));
  free_vector(hits);
  next.movers.active = std::move(moving);
  next.quiet.set(changed, n);
  next.movers.quiet_at_partition = next.quiet.count;
  *this = std::move(next);
  return true;
}

bool PairTracker::Impl::enter_from_pending(const Objects& o,
                                           const std::vector<std::uint64_t>& changed) {
  const auto n = static_cast<std::uint32_t>(o.count);
  if (o.radius.empty()) return false;
  std::vector<std::uint32_t> moving;
  for (std::size_t w = 0; w < changed.size(); ++w)
    for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
      moving.push_back(
          static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b))));
  if (moving.size() * kMoversShare > n) return false;
  if (o.kind != nullptr)  // the others are the spheres the cells took
    for (std::uint32_t i : moving)
      if (!o.is_sphere(i)) return false;
  // The cells again, over the quiet objects alone: keeping the movers'
  // stale records took the own memory at scaled-even 1 024 000 from 54.8
  // to 70.3 B/object for as long as no new partition came.
  std::vector<std::uint32_t> still;
  still.reserve(n - moving.size());
  for (std::uint32_t i = 0; i < n; ++i)
    if (!test_bit(changed, i)) still.push_back(i);
  // The pending cells go first: the new ones then take their blocks
  // (big_blocks.cpp) rather than fresh pages. At scaled-even 1 024 000,
  // where this is the second call of a process, the build took 120-140 ms
  // with them kept to the end, 50-53 without (timed inside the call, on
  // one core).
  movers.quiet_cells = detail::SphereCells{};
  detail::SphereCells cells;
  if (!build_quiet_cells(cells, o, still)) return false;
  movers.quiet_cells = std::move(cells);
  // (Both bits read, without a branch between them: see erase_if.)
  quiet.hits.erase_if([&](const IndexPair& p) {
    return (static_cast<unsigned>(test_bit(changed, p.i)) |
            static_cast<unsigned>(test_bit(changed, p.j))) != 0;
  });
  quiet.set(changed, count);
  movers.active = std::move(moving);
  movers.woken.clear();
  movers.free_lists();
  movers.quiet_at_partition = quiet.count;
  movers.calls = 0;
  mode = Mode::movers;
  return true;
}

bool PairTracker::Impl::movers_suit(const Objects& o, const Changes& changes,
                                    const std::vector<std::uint64_t>& changed) const {
  if (changes.all || o.count != count || o.radius.empty()) return false;
  if (o.kind != nullptr)  // only a listed object can have changed its kind
    for (std::size_t w = 0; w < changed.size(); ++w)
      for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
        if (!o.is_sphere(w * 64 + static_cast<unsigned>(std::countr_zero(b)))) return false;
  return true;
}

}  // namespace broadphase::arrays
