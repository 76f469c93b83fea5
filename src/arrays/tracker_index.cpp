// The tracker's index (tracker_index.hpp): its build, the renewal of the
// objects that leave their fat box, the compaction that folds the renewed
// ones back into the rows, and its invariants.
#include "tracker_index.hpp"

#include <bit>
#include <stdexcept>
#include <string>
#include <unordered_set>

namespace broadphase::arrays::detail {

// The skin as a distance: `skin` times the median largest half-extent (of
// a sample), so it scales with the objects.
double TrackerIndex::margin(const Objects& o, double skin) {
  const double rel = skin;
  std::vector<double> sample;
  const std::size_t step = std::max<std::size_t>(1, o.count / 1024);
  for (std::size_t i = 0; i < o.count; i += step) sample.push_back(o.shape(i).max_half());
  if (sample.empty()) return 0;
  std::nth_element(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2),
                   sample.end());
  const double m = rel * sample[sample.size() / 2];
  return std::isfinite(m) ? m : 0;
}

void TrackerIndex::build(const Objects& o, double skin, unsigned threads) {
  const std::size_t n = o.count;
  margin_used = margin(o, skin);
  rel_skin = kOwnSkinShare * skin;
  std::vector<AabbF> boxes(n);
  for (std::size_t i = 0; i < n; ++i) boxes[i] = fat_box(o.shape(i));
  grid = ArrayGrid{};
  grid.build(boxes);
  struct Lists {
    std::vector<std::uint32_t> counts;
    std::vector<std::uint32_t> partners;
  };
  const std::size_t rows = grid.probe_count();
  offset.assign(rows + 1, 0);
  partner.clear();
  std::size_t filled = 0;
  run_in_order<Lists>(
      rows, threads,
      [&](std::size_t begin, std::size_t end, Lists& out) {
        out.counts.clear();
        out.partners.clear();
        for (std::size_t k = begin; k < end; ++k) {
          const std::size_t before = out.partners.size();
          // A big object's partners have no place yet: their indices
          // until `adopt` gives them one below.
          grid.probe(k, [&](std::uint32_t j, std::uint32_t at) {
            out.partners.push_back(at == ArrayGrid::kNoPlace ? j : at);
          });
          out.counts.push_back(static_cast<std::uint32_t>(out.partners.size() - before));
        }
      },
      [&](Lists& l) {
        for (std::uint32_t c : l.counts) {
          offset[filled + 1] = offset[filled] + c;
          ++filled;
        }
        partner.insert(partner.end(), l.partners.begin(), l.partners.end());
        return true;
      });
  partner.shrink_to_fit();
  adopt(boxes);
  for (std::size_t k = rows - grid.big().size(); k < rows; ++k)
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p) partner[p] = place[partner[p]];
  renewed.assign((n + 63) / 64, 0);
  renewed.shrink_to_fit();
  renewed_list.clear();
  renewed_list.shrink_to_fit();
  loose.clear();
  loose.shrink_to_fit();
  fresh = true;
}

void TrackerIndex::adopt(const std::vector<AabbF>& by_object) {
  const std::size_t n = by_object.size();
  fat.resize(n);
  fat.shrink_to_fit();
  place.resize(n);
  place.shrink_to_fit();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t i = grid.probe_object(k);
    place[i] = static_cast<std::uint32_t>(k);
    fat[k] = by_object[i];
  }
  grid.slim(fat);
}

void TrackerIndex::renew(const std::vector<std::uint32_t>& leave, QuietSet& quiet) {
  // Which objects are renewed now: their old candidates go.
  std::vector<std::uint64_t> now((count() + 63) / 64, 0), now_at(now.size(), 0);
  for (std::uint32_t i : leave) {
    set_bit(now, i);
    set_bit(now_at, place[i]);
  }
  std::erase_if(loose, [&](const LoosePair& p) {
    return test_bit(now_at, p.a) || test_bit(now_at, p.b & kIndexMask);
  });
  for (std::uint32_t i : leave) {
    if (!is_renewed(i)) renewed_list.push_back(i);
    set_bit(renewed, i);
    if (quiet.has(i)) quiet.wake(i);
  }
  auto add_at = [&](std::uint32_t ki, std::uint32_t kj) {  // two places
    const IndexPair q = ordered(ki, kj);
    loose.push_back({q.i, q.j});
  };
  auto add = [&](std::uint32_t i, std::uint32_t j) { add_at(place[i], place[j]); };
  // Partners that were not renewed: the kept grid holds their fat boxes.
  // Queried in the probe order, one query reads much of the memory the
  // last one read.
  std::vector<std::uint32_t> by_place(leave);
  std::sort(by_place.begin(), by_place.end(),
            [&](std::uint32_t p, std::uint32_t q) { return place[p] < place[q]; });
  for (std::uint32_t i : by_place)
    grid.query(fat_of(i), [&](std::uint32_t j, std::uint32_t at) {
      if (j != i && !is_renewed(j)) add_at(place[i], at);
    });
  // Partners among the renewed ones (this call's included, each pair once:
  // a pair of two objects renewed now is added by the lower index).
  auto wanted = [&](std::uint32_t i, std::uint32_t j) {
    return j != i && (!test_bit(now, j) || j > i);
  };
  if (renewed_list.size() <= 64) {
    for (std::uint32_t i : leave)
      for (std::uint32_t j : renewed_list)
        if (wanted(i, j) && fat_of(i).overlaps(fat_of(j))) add(i, j);
    return;
  }
  std::vector<AabbF> boxes(renewed_list.size());
  for (std::size_t k = 0; k < boxes.size(); ++k) boxes[k] = fat_of(renewed_list[k]);
  ArrayGrid loose_grid;
  loose_grid.build(boxes);
  for (std::uint32_t i : leave)
    loose_grid.query(fat_of(i), [&](std::uint32_t k) {
      const std::uint32_t j = renewed_list[k];
      if (wanted(i, j)) add(i, j);
    });
}

// A new grid over the current fat boxes and rows in its order, holding the
// same candidates with the same bits: the rows' live entries, then the loose
// pairs of the row's object (as the lower index). No probe, so it costs a
// grid build and two passes over the candidates, against a probe of every
// object for a rebuild.
void TrackerIndex::compact(const Objects& o, const std::vector<std::uint64_t>* changed,
                           QuietSet& quiet, std::size_t spare) {
  const std::size_t count = this->count();
  const std::size_t rows = grid.probe_count();
  // The quiet pairs of objects not renewed, and those the rows give up below.
  std::vector<IndexPair> hits;
  hits.reserve(quiet.hits.size());
  quiet.hits.expand(0, quiet.hits.size(), hits,
                    [&](const IndexPair& q) { return !is_renewed(q.i) && !is_renewed(q.j); });
  std::vector<AabbF> by_object(count);
  for (std::size_t k = 0; k < rows; ++k) by_object[grid.probe_object(k)] = fat[k];
  // With `changed`, the objects it does not list become quiet. A quiet
  // object's box shrinks to its bounds: it never leaves the box unnoticed
  // (the caller lists it when it changes, and it is then renewed), so a
  // skin around it only adds candidates with the movers. The pairs of two
  // quiet objects leave the rows (see `quiet`), and those of a quiet and
  // an active object whose boxes no longer meet are dropped.
  if (changed != nullptr) {
    quiet.set(*changed, count);
    for (std::size_t w = 0; w < quiet.bits.size(); ++w)
      for (std::uint64_t b = quiet.bits[w]; b != 0; b &= b - 1) {
        const auto i =
            static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b)));
        by_object[i] = bounds_f(read_shape(o, i));
      }
  }
  // The passes below read every candidate's state and box by its place
  // (near its row's, as the partners are neighbours in space), not by its
  // object: by object, each was a cache miss (20 s of a compaction at
  // 10 240 000 objects).
  enum : std::uint8_t { kRenewedAt = 1, kQuietAt = 2 };
  std::vector<std::uint8_t> state(rows);
  std::vector<AabbF> box_at(changed != nullptr ? rows : 0);
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t i = grid.probe_object(k);
    state[k] =
        static_cast<std::uint8_t>((is_renewed(i) ? kRenewedAt : 0) |
                                  (changed != nullptr && test_bit(quiet.bits, i) ? kQuietAt : 0));
    if (changed != nullptr) box_at[k] = by_object[i];
  }
  enum class Fate { row, quiet, drop };
  auto fate = [&](std::uint32_t ka, std::uint32_t kb) {  // two places
    if (changed == nullptr) return Fate::row;
    const bool qa = (state[ka] & kQuietAt) != 0, qb = (state[kb] & kQuietAt) != 0;
    if (qa && qb) return Fate::quiet;
    if ((qa || qb) && !box_at[ka].overlaps(box_at[kb])) return Fate::drop;
    return Fate::row;
  };
  // Candidates kept per place, then where they go.
  std::vector<std::uint32_t> cursor(rows, 0);
  for (std::size_t k = 0; k < rows; ++k) {
    if (state[k] & kRenewedAt) continue;
    std::uint32_t c = 0;
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p) {
      const std::uint32_t q = partner[p] & kIndexMask;
      c += !(state[q] & kRenewedAt) && fate(static_cast<std::uint32_t>(k), q) == Fate::row ? 1 : 0;
    }
    cursor[k] = c;
  }
  for (const LoosePair& lp : loose)
    cursor[lp.a] += fate(lp.a, lp.b & kIndexMask) == Fate::row ? 1 : 0;
  // The finest cells stay as wide as the last grid's: the quiet objects'
  // bounds are smaller than their fat boxes, and finer levels would make a
  // renewed object's query read many more rows of cells (2.2x slower frames
  // with renewals at scaled-even 1 024 000).
  ArrayGrid next;
  next.build(by_object, 1, grid.base_cell());
  std::vector<std::uint32_t> next_offset(rows + 1, 0);
  std::vector<std::uint32_t> moved(rows);  // an object's new place, by its old one
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t old = place[next.probe_object(k)];
    moved[old] = static_cast<std::uint32_t>(k);
    next_offset[k + 1] = next_offset[k] + cursor[old];
  }
  for (std::size_t k = 0; k < rows; ++k) cursor[k] = next_offset[moved[k]];
  std::vector<std::uint32_t> next_partner(next_offset[rows]);
  auto take = [&](std::uint32_t ka, std::uint32_t kb, std::uint32_t bit) {
    switch (fate(ka, kb)) {
      case Fate::row:
        next_partner[cursor[ka]++] = moved[kb] | bit;
        break;
      case Fate::quiet:
        if (bit != 0) hits.push_back(ordered(grid.probe_object(ka), grid.probe_object(kb)));
        break;
      case Fate::drop:
        break;
    }
  };
  for (std::size_t k = 0; k < rows; ++k) {
    if (state[k] & kRenewedAt) continue;
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p)
      if (const std::uint32_t q = partner[p] & kIndexMask; !(state[q] & kRenewedAt))
        take(static_cast<std::uint32_t>(k), q, partner[p] & kOverlapBit);
  }
  for (const LoosePair& lp : loose) take(lp.a, lp.b & kIndexMask, lp.b & kOverlapBit);
  quiet.hits.assign(hits, count, spare);
  free_vector(hits);
  grid = std::move(next);
  adopt(by_object);
  offset = std::move(next_offset);
  partner = std::move(next_partner);
  std::fill(renewed.begin(), renewed.end(), 0);
  renewed_list.clear();
  renewed_list.shrink_to_fit();
  loose.clear();
  loose.shrink_to_fit();
}

TrackerIndex::Leavers TrackerIndex::leavers(const Objects& o, bool all,
                                            const std::vector<std::uint64_t>& changed,
                                            std::size_t changed_count, const QuietSet& quiet) {
  Leavers out;
  const auto n = static_cast<std::uint32_t>(o.count);
  auto look = [&](std::uint32_t i) {
    out.quiet_changed += quiet.has(i) ? 1 : 0;
    if (!contained(o, i)) {
      fat_of(i) = renewed_box(o.shape(i), fat_of(i));
      out.renew.push_back(i);
      ++out.left;
    } else if (quiet.has(i)) {
      out.renew.push_back(i);
    }
  };
  // Each check reads the object's fat box, kept in the grid's order, so a
  // cache miss: the boxes of the objects a few ahead are asked for first.
  constexpr std::uint32_t kAhead = 16;
  if (all) {
    for (std::uint32_t i = 0; i < n; ++i) {
      if (i + kAhead < n) __builtin_prefetch(&fat_of(i + kAhead));
      look(i);
    }
  } else {
    std::vector<std::uint32_t> list;
    list.reserve(changed_count);
    for (std::size_t w = 0; w < changed.size(); ++w)
      for (std::uint64_t b = changed[w]; b != 0; b &= b - 1)
        list.push_back(
            static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(std::countr_zero(b))));
    for (std::size_t r = 0; r < list.size(); ++r) {
      if (r + kAhead < list.size()) __builtin_prefetch(&fat_of(list[r + kAhead]));
      look(list[r]);
    }
  }
  return out;
}

void TrackerIndex::scan(const Objects& o, bool all, const std::vector<std::uint64_t>& changed,
                        std::size_t changed_count, const QuietSet& quiet,
                        const ArrayOptions& options, const PairSink& sink, ArrayCallStats& stats) {
  const auto n = static_cast<std::uint32_t>(o.count);
  const bool test_all = all || fresh;
  auto is_changed = [&](std::uint32_t k) { return test_all || test_bit(changed, k); };
  // Until every row is done (a sink may stop early or throw), the bits are
  // not to be trusted.
  fresh = true;

  const std::size_t rows = offset.size() - 1;
  const bool any_renewed = !renewed_list.empty();
  Emitter emit(sink, options.sorted, stats, PairFilterColumns::of(o));
  const unsigned threads = thread_count(options.threads);
  // The scan over the rows, then over the renewed objects' candidates in
  // the order they were found, with shapes from `rd`.
  auto scan = [&](const auto& rd) {
    const bool go_on = run_in_order<PairChunk>(
        rows, threads,
        [&](std::size_t begin, std::size_t end, PairChunk& out) {
          out.pairs.clear();
          out.tests = 0;
          for (std::size_t k = begin; k < end; ++k) {
            if (k + kPrefetchRows < rows)
              for (std::uint32_t p = offset[k + kPrefetchRows]; p < offset[k + kPrefetchRows + 1];
                   ++p)
                rd.prefetch(partner[p] & kIndexMask);
            const std::uint32_t s = offset[k], e = offset[k + 1];
            if (s == e) continue;
            const std::uint32_t i = grid.probe_object(k);
            if (any_renewed && is_renewed(i)) continue;  // its pairs are loose
            const bool i_changed = is_changed(i);
            for (std::uint32_t p = s; p < e; ++p) {
              std::uint32_t& entry = partner[p];
              const std::uint32_t q = entry & kIndexMask;
              const std::uint32_t j = grid.probe_object(q);
              if (any_renewed && is_renewed(j)) continue;
              bool hit;
              if (i_changed || is_changed(j)) {
                ++out.tests;
                hit = overlaps(rd.row(k, i), rd.row(q, j));
                entry = q | (hit ? kOverlapBit : 0);
              } else {
                hit = (entry & kOverlapBit) != 0;
              }
              if (hit) out.pairs.push_back(ordered(i, j));
            }
          }
        },
        [&](PairChunk& c) { return emit.deliver(c); });
    if (go_on)
      run_in_order<PairChunk>(
          loose.size(), threads,
          [&](std::size_t begin, std::size_t end, PairChunk& out) {
            out.pairs.clear();
            out.tests = 0;
            for (std::size_t p = begin; p < end; ++p) {
              LoosePair& lp = loose[p];
              const std::uint32_t ka = lp.a, kb = lp.b & kIndexMask;
              const std::uint32_t i = grid.probe_object(ka), j = grid.probe_object(kb);
              bool hit;
              if (is_changed(i) || is_changed(j)) {
                ++out.tests;
                hit = overlaps(rd.row(ka, i), rd.row(kb, j));
                lp.b = kb | (hit ? kOverlapBit : 0);
              } else {
                hit = (lp.b & kOverlapBit) != 0;
              }
              if (hit) out.pairs.push_back(ordered(i, j));
            }
          },
          [&](PairChunk& c) { return emit.deliver(c); });
    if (!go_on || emit.stopped()) return;
    quiet.deliver(emit, threads, any_renewed);
  };
  // When many objects changed, most objects take part in a test, and the
  // tests' reads of the caller's columns (one cache miss a column, in the
  // caller's order) dominate the call: the shapes are first copied, in one
  // sequential pass over the columns, into the rows' order, where a row's
  // partners lie near it (docs/arrays.md). With few changes, the tests
  // read the columns directly.
  if ((test_all ? n : changed_count) * kGatherShare >= o.count) {
    detail::BigVector<Shape> now(rows);
    for (std::uint32_t i = 0; i < n; ++i) now[place[i]] = read_shape(o, i);
    struct Gathered {
      const Shape* now;
      // Object i's shape, at place k.
      const Shape& row(std::size_t k, std::uint32_t) const { return now[k]; }
      void prefetch(std::uint32_t q) const { __builtin_prefetch(now + q); }
    };
    scan(Gathered{now.data()});
  } else {
    struct Direct {
      const Objects& o;
      Shape row(std::size_t, std::uint32_t i) const { return read_shape(o, i); }
      void prefetch(std::uint32_t) const {}
    };
    scan(Direct{o});
  }
  emit.finish();
}

std::size_t TrackerIndex::memory_bytes() const {
  return fat.capacity() * sizeof(AabbF) + grid.memory_bytes() + grid.slim_bytes() +
         (place.capacity() + offset.capacity() + partner.capacity() + renewed_list.capacity()) *
             sizeof(std::uint32_t) +
         renewed.capacity() * sizeof(std::uint64_t) + loose.capacity() * sizeof(LoosePair);
}

void TrackerIndex::check(const Objects& objects, const QuietSet& quiet) const {
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  const std::size_t n = count();
  if (fat.size() != n || place.size() != n) fail("one fat box and place per object");
  const std::size_t rows = grid.probe_count();
  if (rows != n) fail("one candidate row per object");
  if (offset.size() != rows + 1 || offset[0] != 0 || offset[rows] != partner.size())
    fail("candidate offsets do not span the partner list");
  if (renewed.size() != (n + 63) / 64) fail("one renewed bit per object");
  // The renewed list and bits agree, without repeats.
  std::size_t marked = 0;
  for (std::uint32_t i = 0; i < n; ++i) marked += is_renewed(i) ? 1 : 0;
  if (marked != renewed_list.size()) fail("renewed bits and list disagree");
  {
    std::vector<char> listed(n, 0);
    for (std::uint32_t i : renewed_list) {
      if (i >= n || !is_renewed(i) || listed[i])
        fail("renewed list holds " + std::to_string(i) + " wrongly or twice");
      listed[i] = 1;
    }
  }
  if (!quiet.bits.empty() && quiet.bits.size() != (n + 63) / 64) fail("one quiet bit per object");
  {
    std::size_t quiet_seen = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      quiet_seen += quiet.has(i) ? 1 : 0;
      if (quiet.has(i) && is_renewed(i))
        fail("object " + std::to_string(i) + " is both quiet and renewed");
    }
    if (quiet_seen != quiet.count) fail("quiet bits and count disagree");
  }
  std::vector<char> has_row(n, 0);
  std::unordered_set<std::uint64_t> seen;
  auto check_pair = [&](std::uint32_t i, std::uint32_t entry) {
    const std::uint32_t j = entry & kIndexMask;
    if (j >= n || j == i) fail("candidate partner out of range at " + std::to_string(i));
    const IndexPair q = ordered(i, j);
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second)
      fail("candidate pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") listed twice");
    if (!fat_of(i).overlaps(fat_of(j)))
      fail("candidate pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") has fat boxes apart");
    if (!fresh && ((entry & kOverlapBit) != 0) != overlaps(objects.shape(i), objects.shape(j)))
      fail("the overlap bit of (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") is stale");
  };
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t i = grid.probe_object(k);
    if (i >= n || has_row[i]) fail("row " + std::to_string(k) + " has a bad or repeated owner");
    if (place[i] != k) fail("object " + std::to_string(i) + " is not at its row's place");
    has_row[i] = 1;
    if (offset[k] > offset[k + 1]) fail("candidate offsets decrease at " + std::to_string(k));
    if (!contained(objects, i)) fail("object " + std::to_string(i) + " lies outside its fat box");
    if (is_renewed(i)) continue;  // dead row
    for (std::uint32_t p = offset[k]; p < offset[k + 1]; ++p) {
      if ((partner[p] & kIndexMask) >= rows)
        fail("candidate place out of range at " + std::to_string(k));
      const std::uint32_t j = partner_object(partner[p]);
      if (is_renewed(j)) continue;  // dead entry
      if (quiet.has(i) && quiet.has(j))
        fail("candidate pair of quiet " + std::to_string(i) + " and " + std::to_string(j) +
             " left in the rows");
      check_pair(i, j | (partner[p] & kOverlapBit));
    }
  }
  for (const LoosePair& lp : loose) {
    const std::uint32_t kb = lp.b & kIndexMask;
    if (lp.a >= kb || kb >= rows)
      fail("loose pair at places (" + std::to_string(lp.a) + ", " + std::to_string(kb) +
           ") out of order or range");
    const std::uint32_t i = grid.probe_object(lp.a), j = grid.probe_object(kb);
    if (!is_renewed(i) && !is_renewed(j))
      fail("loose pair (" + std::to_string(i) + ", " + std::to_string(j) +
           ") has no renewed object");
    check_pair(i, j | (lp.b & kOverlapBit));
  }
  quiet.hits.for_each([&](const IndexPair& q) {
    if (q.i >= q.j || q.j >= n)
      fail("quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") out of order or range");
    if (is_renewed(q.i) || is_renewed(q.j)) return;  // dead
    const std::string name =
        "quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) + ")";
    if (!quiet.has(q.i) || !quiet.has(q.j)) fail(name + " has an object that is not quiet");
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second) fail(name + " listed twice");
    if (!overlaps(objects.shape(q.i), objects.shape(q.j))) fail(name + " does not overlap");
  });
  // Completeness: every pair of overlapping fat boxes is a candidate
  // (quadratic, so checked only on small sets).
  if (n <= 3000)
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (fat_of(i).overlaps(fat_of(j)) && !seen.count((std::uint64_t(i) << 32) | j) &&
            !(quiet.has(i) && quiet.has(j) && !overlaps(objects.shape(i), objects.shape(j))))
          fail("overlapping fat boxes of " + std::to_string(i) + " and " + std::to_string(j) +
               " are not candidates");
}

}  // namespace broadphase::arrays::detail
