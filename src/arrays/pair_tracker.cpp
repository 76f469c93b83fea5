// The lean path's tracker (arrays.hpp, PairTracker): a multi-level hashed
// grid over skin-fattened float boxes kept between calls, candidate rows
// per object, renewals of objects that leave their box, quiet objects, and
// calls afresh when motion outruns the skin; for sets of spheres that are
// mostly quiet, movers mode instead (no index of the movers at all); exact
// tests read from the caller's data.
#include "pair_tracker_impl.hpp"

namespace broadphase::arrays {

// The skin as a distance: skin() times the median largest half-extent (of
// a sample), so it scales with the objects.
double PairTracker::Impl::margin(const Objects& o) const {
  const double rel = skin();
  std::vector<double> sample;
  const std::size_t step = std::max<std::size_t>(1, o.count / 1024);
  for (std::size_t i = 0; i < o.count; i += step) sample.push_back(o.shape(i).max_half());
  if (sample.empty()) return 0;
  std::nth_element(sample.begin(), sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2),
                   sample.end());
  const double m = rel * sample[sample.size() / 2];
  return std::isfinite(m) ? m : 0;
}

void PairTracker::Impl::rebuild(const Objects& o) {
  const std::size_t n = o.count;
  movers = false;
  movers_refused = false;
  pending = false;
  quiet_cells = detail::SphereCells{};
  free_vector(active);
  free_vector(woken);
  free_mover_lists();
  margin_used = margin(o);
  rel_skin = kOwnSkinShare * skin();
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
      rows, thread_count(options.threads),
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
  quiet.clear();
  quiet.shrink_to_fit();
  quiet_count = 0;
  quiet_hits.clear();
  count = n;
  built = true;
  fresh = true;
}

void PairTracker::Impl::set_quiet(const std::vector<std::uint64_t>& changed) {
  quiet.resize(changed.size());
  for (std::size_t w = 0; w < changed.size(); ++w) quiet[w] = ~changed[w];
  if (count % 64 != 0) quiet.back() &= (std::uint64_t{1} << (count % 64)) - 1;
  quiet_count = 0;
  for (std::uint64_t w : quiet) quiet_count += static_cast<std::size_t>(std::popcount(w));
}

void PairTracker::Impl::adopt(const std::vector<AabbF>& by_object) {
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

void PairTracker::Impl::renew(const std::vector<std::uint32_t>& leave) {
  // Which objects are renewed now: their old candidates go.
  std::vector<std::uint64_t> now((count + 63) / 64, 0), now_at(now.size(), 0);
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
    if (is_quiet(i)) {
      quiet[i >> 6] &= ~(std::uint64_t{1} << (i & 63));
      --quiet_count;
    }
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
void PairTracker::Impl::compact(const Objects& o, const std::vector<std::uint64_t>* changed) {
  const std::size_t rows = grid.probe_count();
  // The quiet pairs of objects not renewed, and those the rows give up below.
  std::vector<IndexPair> hits;
  hits.reserve(quiet_hits.size());
  quiet_hits.expand(0, quiet_hits.size(), hits,
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
    set_quiet(*changed);
    for (std::size_t w = 0; w < quiet.size(); ++w)
      for (std::uint64_t b = quiet[w]; b != 0; b &= b - 1) {
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
    state[k] = static_cast<std::uint8_t>((is_renewed(i) ? kRenewedAt : 0) |
                                         (changed != nullptr && test_bit(quiet, i) ? kQuietAt : 0));
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
  quiet_hits.assign(hits, count, spare_half());
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

PairTracker::PairTracker(const ArrayOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
}
PairTracker::~PairTracker() = default;
PairTracker::PairTracker(PairTracker&&) noexcept = default;
PairTracker& PairTracker::operator=(PairTracker&&) noexcept = default;

bool PairTracker::Impl::deliver_quiet(Emitter& emit, unsigned threads, bool any_dead) const {
  if (!any_dead && quiet_hits.plain()) return emit.deliver_slices(quiet_hits.pairs());
  return run_in_order<PairChunk>(
      quiet_hits.size(), threads,
      [&](std::size_t begin, std::size_t end, PairChunk& out) {
        out.pairs.clear();
        out.tests = 0;
        if (any_dead)
          quiet_hits.expand(begin, end, out.pairs,
                            [&](const IndexPair& q) { return is_quiet(q.i) && is_quiet(q.j); });
        else
          quiet_hits.expand(begin, end, out.pairs, [](const IndexPair&) { return true; });
      },
      [&](PairChunk& c) { return emit.deliver(c); });
}

ArrayCallStats PairTracker::find_pairs(const Objects& objects, const PairSink& sink,
                                       const Changes& changes) {
  Impl& im = *impl_;
  // Everything that can throw on bad input runs before the tracker changes.
  // A movers call reads only the objects listed (and movers whose values
  // it checked when they were listed): it checks the listed ones alone,
  // as it reads them (Impl::movers_call).
  // Any other call, and a movers call that partitions again or leaves the
  // mode, checks every value first (check_all).
  const bool listed_only = !changes.all && im.movers && !im.pending && objects.count == im.count;
  bool checked = !listed_only;
  auto check_all = [&] {
    if (!checked) check_objects(objects);
    checked = true;
  };
  if (!listed_only) check_objects(objects);
  if (objects.count > kMaxTracked)
    throw InvalidObjects("objects: " + std::to_string(objects.count) +
                             " objects, more than a tracker can name (" +
                             std::to_string(kMaxTracked) + ")",
                         SIZE_MAX);
  if (!changes.all)
    for (std::uint32_t k : changes.indices)
      if (k >= objects.count)
        throw InvalidObjects("changes: index " + std::to_string(k) + " is not below the count " +
                                 std::to_string(objects.count),
                             k);

  ArrayCallStats stats;
  const auto n = static_cast<std::uint32_t>(objects.count);
  bool rebuild = !im.built || objects.count != im.count;
  // The objects that left their fat box: renewed alone, unless so many
  // left in this call that a rebuild is cheaper. (Renewal and compaction
  // run on the calling thread only.)
  // Which objects changed: a pair of unchanged objects keeps the answer of
  // the last call (its bit), so only pairs with a changed object are tested.
  // (The renewed pairs of this call all have a changed object.)
  std::vector<std::uint64_t> changed;
  std::size_t changed_count = n;
  if (!changes.all) {
    changed.assign((objects.count + 63) / 64, 0);
    changed_count = 0;
    for (std::uint32_t k : changes.indices)
      if (!test_bit(changed, k)) {
        set_bit(changed, k);
        ++changed_count;
      }
  }
  // After a call afresh with no index (`pending`, below), a call that lists
  // its changes on as many objects enters movers mode if it can.
  if (im.pending && !changes.all && objects.count == im.count &&
      (im.quiet_cells.size() == objects.count ? im.enter_from_pending(objects, changed)
                                              : im.enter_movers(objects, changed))) {
    stats = im.movers_call(objects, changed, sink, false);
    stats.compacted = true;
    return stats;
  }
  // Movers mode: a call that lists its changes on the same spheres stays in
  // it (after a new partition if due); any other leaves it for the index.
  if (im.movers) {
    bool take = im.movers_suit(objects, changes, changed);
    bool partitioned = false;
    if (take && im.movers_stale(changed, changed_count)) {
      check_all();
      take = im.enter_movers(objects, changed);
      partitioned = take;
    }
    if (take) {
      // (The values listed are checked as the call reads them, unless
      // check_all did.)
      stats = im.movers_call(objects, changed, sink, !checked);
      stats.compacted = partitioned;
      return stats;
    }
    check_all();
    rebuild = true;
  }
  // Renewed in this call: the objects that left their fat box, and the
  // quiet ones the caller changed (woken), unless so many that a rebuild
  // is cheaper. (Renewal and compaction run on the calling thread only.)
  std::vector<std::uint32_t> renew;
  std::size_t left = 0, quiet_changed = 0;
  bool outran = false;  // a rebuild is due because objects left their boxes
  if (!rebuild) {
    auto look = [&](std::uint32_t i) {
      quiet_changed += im.is_quiet(i) ? 1 : 0;
      if (!im.contained(objects, i)) {
        im.fat_of(i) = im.renewed_box(objects.shape(i), im.fat_of(i));
        renew.push_back(i);
        ++left;
      } else if (im.is_quiet(i)) {
        renew.push_back(i);
      }
    };
    // Each check reads the object's fat box, kept in the grid's order, so a
    // cache miss: the boxes of the objects a few ahead are asked for first.
    constexpr std::uint32_t kAhead = 16;
    if (changes.all) {
      for (std::uint32_t i = 0; i < n; ++i) {
        if (i + kAhead < n) __builtin_prefetch(&im.fat_of(i + kAhead));
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
        if (r + kAhead < list.size()) __builtin_prefetch(&im.fat_of(list[r + kAhead]));
        look(list[r]);
      }
    }
    rebuild = static_cast<double>(renew.size()) > kRebuildFraction * static_cast<double>(n);
    outran = rebuild;
  }
  // Motion outran the skin: so many objects left their fat boxes that the
  // index would be built again. A set of spheres in cells that are not
  // crowded is then searched afresh by the one-shot kernel, several times
  // cheaper than a build, and so are the next kAfreshCalls calls, without
  // an index (the tracker holds nothing meanwhile); the call after them
  // builds one again, to see whether the motion has slowed. Measured on
  // one core, all-moving 20 000 (every object moves every frame, mostly
  // past the skin): 11.0 ms a call on the index, 1.3 ms afresh. Where the
  // cells are crowded (the study's scenes at 6 400: calls afresh 1.2 to 1.5
  // times the index's between builds), the index is built as before.
  if (outran || (rebuild && im.afresh_left > 0)) {
    detail::SphereCells cells;
    if (cells.build(objects) && cells.crowd() <= kAfreshCrowd) {
      const std::uint32_t afresh_left = outran ? kAfreshCalls : im.afresh_left - 1;
      const ArrayOptions options = im.options;
      clear();
      im.afresh_left = afresh_left;
      stats = cell_pairs(cells, sink, options);
      stats.afresh = true;
      return stats;
    }
    im.afresh_left = 0;
  }
  // No index yet (a first call, a new count, movers mode left): a set that
  // movers mode may take is searched afresh, holding nothing, and the next
  // call that lists its changes partitions it straight away; a next call
  // that does not builds the index. The index's build (1.0-1.2 s at
  // scaled-even 1 024 000, three one-shot calls' worth) is then not paid
  // by a caller that lists its changes.
  // The pairs are kept, with the cells: the next call enters movers mode
  // by sorting the quiet objects into cells of their own and dropping the
  // listed objects' pairs, without finding the quiet pairs again
  // (scaled-even 1 024 000, that call 410 -> 324 ms on one core).
  // The cells are those the quiet spheres take (build_quiet_cells):
  // coarse where the radii spread. The kernel's own, four cells a sphere
  // over three grids there, took this call (the first of a process, its
  // pages fresh) 454 ms against 278, one run each on one core; its
  // starts alone were 16 MB.
  if (rebuild && !im.pending) {
    detail::SphereCells cells;
    if (build_quiet_cells(cells, objects, {})) {
      const ArrayOptions options = im.options;
      const std::uint32_t quiet_after = im.quiet_after;
      clear();
      // Reserved, not written: untouched pages cost nothing. Grown by
      // doubling, the 2.58 million pairs of scaled-even 1 024 000 took
      // 15-20 ms more in copies and fresh pages.
      std::vector<IndexPair> all;
      all.reserve(std::min<std::size_t>(4 * objects.count, std::size_t{1} << 26));
      stats = cell_pairs(cells, sink, options, &all);
      im.quiet_after = quiet_after;
      im.pending = true;
      im.count = objects.count;
      if (!stats.stopped) {  // (a sink that stopped early saw only some)
        im.quiet_hits.assign(all, objects.count, im.spare_half());
        im.quiet_cells = std::move(cells);
      }
      stats.afresh = true;
      return stats;
    }
  }
  // Objects that did not change in this call while their candidates are
  // still scanned become quiet, when they are many (a pass over the rows).
  if (changes.all) {
    im.listed_calls = 0;
    if (im.quiet_count > 0) im.quiet_after = std::min<std::uint32_t>(im.quiet_after * 4, 1u << 20);
  } else {
    ++im.listed_calls;
  }
  const bool bits_hold = im.built && !im.fresh && !changes.all && im.listed_calls >= im.quiet_after;
  auto partition_pays = [&] {
    return bits_hold && (n - im.quiet_count) - (changed_count - quiet_changed) > n / 8;
  };
  // The default skin outrun by a share of the changed objects at one call:
  // built again, once, with a wider one (kSkinGrowth). A skin the caller
  // chose stays as it is.
  if (!rebuild && im.built && im.options.skin <= 0 && im.skin_growth == 1 &&
      renew.size() * kSkinGrowShare > changed_count) {
    im.skin_growth = kSkinGrowth;
    rebuild = true;
  }
  if (rebuild) {
    im.rebuild(objects);
    stats.rebuilt = true;
  } else {
    const bool partition_now = partition_pays();  // before renewals change the quiet count
    // Movers mode, at a partition or, while objects are quiet, as soon as
    // the set suits it (a box among the spheres may have gone).
    if ((partition_now || (bits_hold && im.quiet_count > 0 && !im.movers_refused)) &&
        im.enter_movers(objects, changed)) {
      stats = im.movers_call(objects, changed, sink, false);
      stats.compacted = true;
      return stats;
    }
    if (!renew.empty()) {
      im.renew(renew);
      stats.renewed = left;
      stats.woken = quiet_changed;
    }
    if (partition_now || (!renew.empty() && im.wants_compaction())) {
      im.compact(objects, bits_hold ? &changed : nullptr);
      stats.compacted = true;
    }
  }
  const bool test_all = changes.all || im.fresh;
  auto is_changed = [&](std::uint32_t k) { return test_all || test_bit(changed, k); };
  // Until every row is done (a sink may stop early or throw), the bits are
  // not to be trusted.
  im.fresh = true;

  const std::size_t rows = im.offset.size() - 1;
  const bool any_renewed = !im.renewed_list.empty();
  Emitter emit(sink, im.options.sorted, stats);
  const unsigned threads = thread_count(im.options.threads);
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
              for (std::uint32_t p = im.offset[k + kPrefetchRows];
                   p < im.offset[k + kPrefetchRows + 1]; ++p)
                rd.prefetch(im.partner[p] & kIndexMask);
            const std::uint32_t s = im.offset[k], e = im.offset[k + 1];
            if (s == e) continue;
            const std::uint32_t i = im.grid.probe_object(k);
            if (any_renewed && im.is_renewed(i)) continue;  // its pairs are loose
            const bool i_changed = is_changed(i);
            for (std::uint32_t p = s; p < e; ++p) {
              std::uint32_t& entry = im.partner[p];
              const std::uint32_t q = entry & kIndexMask;
              const std::uint32_t j = im.grid.probe_object(q);
              if (any_renewed && im.is_renewed(j)) continue;
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
          im.loose.size(), threads,
          [&](std::size_t begin, std::size_t end, PairChunk& out) {
            out.pairs.clear();
            out.tests = 0;
            for (std::size_t p = begin; p < end; ++p) {
              LoosePair& lp = im.loose[p];
              const std::uint32_t ka = lp.a, kb = lp.b & kIndexMask;
              const std::uint32_t i = im.grid.probe_object(ka), j = im.grid.probe_object(kb);
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
    im.deliver_quiet(emit, threads, any_renewed);
  };
  // When many objects changed, most objects take part in a test, and the
  // tests' reads of the caller's columns (one cache miss a column, in the
  // caller's order) dominate the call: the shapes are first copied, in one
  // sequential pass over the columns, into the rows' order, where a row's
  // partners lie near it (docs/arrays.md). With few changes, the tests
  // read the columns directly.
  if ((test_all ? n : changed_count) * kGatherShare >= objects.count) {
    detail::BigVector<Shape> now(rows);
    for (std::uint32_t i = 0; i < n; ++i) now[im.place[i]] = read_shape(objects, i);
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
    scan(Direct{objects});
  }
  emit.finish();
  im.fresh = stats.stopped;
  stats.quiet = im.quiet_count;
  return stats;
}

ArrayCallStats PairTracker::find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                                       const Changes& changes) {
  return find_pairs(objects, append_to(out), changes);
}

std::size_t PairTracker::memory_bytes() const {
  const Impl& im = *impl_;
  return sizeof(Impl) + im.fat.capacity() * sizeof(AabbF) + im.grid.memory_bytes() +
         im.quiet.capacity() * sizeof(std::uint64_t) + im.quiet_hits.memory_bytes() +
         im.grid.slim_bytes() +
         (im.place.capacity() + im.offset.capacity() + im.partner.capacity() +
          im.renewed_list.capacity()) *
             sizeof(std::uint32_t) +
         im.renewed.capacity() * sizeof(std::uint64_t) + im.loose.capacity() * sizeof(LoosePair) +
         im.quiet_cells.memory_bytes() +
         (im.active.capacity() + im.woken.capacity() + im.list_pool.capacity() +
          im.list_of.capacity()) *
             sizeof(std::uint32_t) +
         im.mover_lists.capacity() * sizeof(Impl::MoverList);
}

void PairTracker::clear() {
  const ArrayOptions options = impl_->options;
  *impl_ = Impl{};
  impl_->options = options;
}

void PairTracker::validate(const Objects& objects) const {
  const Impl& im = *impl_;
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  if (!im.built) return;
  if (im.count != objects.count) fail("count differs from the last call's objects");
  const std::size_t n = im.count;
  if (im.movers) {
    im.check_movers(objects);
    return;
  }
  if (im.fat.size() != n || im.place.size() != n) fail("one fat box and place per object");
  const std::size_t rows = im.grid.probe_count();
  if (rows != n) fail("one candidate row per object");
  if (im.offset.size() != rows + 1 || im.offset[0] != 0 || im.offset[rows] != im.partner.size())
    fail("candidate offsets do not span the partner list");
  if (im.renewed.size() != (n + 63) / 64) fail("one renewed bit per object");
  // The renewed list and bits agree, without repeats.
  std::size_t marked = 0;
  for (std::uint32_t i = 0; i < n; ++i) marked += im.is_renewed(i) ? 1 : 0;
  if (marked != im.renewed_list.size()) fail("renewed bits and list disagree");
  {
    std::vector<char> listed(n, 0);
    for (std::uint32_t i : im.renewed_list) {
      if (i >= n || !im.is_renewed(i) || listed[i])
        fail("renewed list holds " + std::to_string(i) + " wrongly or twice");
      listed[i] = 1;
    }
  }
  if (!im.quiet.empty() && im.quiet.size() != (n + 63) / 64) fail("one quiet bit per object");
  {
    std::size_t quiet = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      quiet += im.is_quiet(i) ? 1 : 0;
      if (im.is_quiet(i) && im.is_renewed(i))
        fail("object " + std::to_string(i) + " is both quiet and renewed");
    }
    if (quiet != im.quiet_count) fail("quiet bits and count disagree");
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
    if (!im.fat_of(i).overlaps(im.fat_of(j)))
      fail("candidate pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") has fat boxes apart");
    if (!im.fresh && ((entry & kOverlapBit) != 0) != overlaps(objects.shape(i), objects.shape(j)))
      fail("the overlap bit of (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") is stale");
  };
  for (std::size_t k = 0; k < rows; ++k) {
    const std::uint32_t i = im.grid.probe_object(k);
    if (i >= n || has_row[i]) fail("row " + std::to_string(k) + " has a bad or repeated owner");
    if (im.place[i] != k) fail("object " + std::to_string(i) + " is not at its row's place");
    has_row[i] = 1;
    if (im.offset[k] > im.offset[k + 1]) fail("candidate offsets decrease at " + std::to_string(k));
    if (!im.contained(objects, i))
      fail("object " + std::to_string(i) + " lies outside its fat box");
    if (im.is_renewed(i)) continue;  // dead row
    for (std::uint32_t p = im.offset[k]; p < im.offset[k + 1]; ++p) {
      if ((im.partner[p] & kIndexMask) >= rows)
        fail("candidate place out of range at " + std::to_string(k));
      const std::uint32_t j = im.partner_object(im.partner[p]);
      if (im.is_renewed(j)) continue;  // dead entry
      if (im.is_quiet(i) && im.is_quiet(j))
        fail("candidate pair of quiet " + std::to_string(i) + " and " + std::to_string(j) +
             " left in the rows");
      check_pair(i, j | (im.partner[p] & kOverlapBit));
    }
  }
  for (const LoosePair& lp : im.loose) {
    const std::uint32_t kb = lp.b & kIndexMask;
    if (lp.a >= kb || kb >= rows)
      fail("loose pair at places (" + std::to_string(lp.a) + ", " + std::to_string(kb) +
           ") out of order or range");
    const std::uint32_t i = im.grid.probe_object(lp.a), j = im.grid.probe_object(kb);
    if (!im.is_renewed(i) && !im.is_renewed(j))
      fail("loose pair (" + std::to_string(i) + ", " + std::to_string(j) +
           ") has no renewed object");
    check_pair(i, j | (lp.b & kOverlapBit));
  }
  im.quiet_hits.for_each([&](const IndexPair& q) {
    if (q.i >= q.j || q.j >= n)
      fail("quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) +
           ") out of order or range");
    if (im.is_renewed(q.i) || im.is_renewed(q.j)) return;  // dead
    const std::string name =
        "quiet pair (" + std::to_string(q.i) + ", " + std::to_string(q.j) + ")";
    if (!im.is_quiet(q.i) || !im.is_quiet(q.j)) fail(name + " has an object that is not quiet");
    if (!seen.insert((std::uint64_t(q.i) << 32) | q.j).second) fail(name + " listed twice");
    if (!overlaps(objects.shape(q.i), objects.shape(q.j))) fail(name + " does not overlap");
  });
  // Completeness: every pair of overlapping fat boxes is a candidate
  // (quadratic, so checked only on small sets).
  if (n <= 3000)
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (im.fat_of(i).overlaps(im.fat_of(j)) && !seen.count((std::uint64_t(i) << 32) | j) &&
            !(im.is_quiet(i) && im.is_quiet(j) && !overlaps(objects.shape(i), objects.shape(j))))
          fail("overlapping fat boxes of " + std::to_string(i) + " and " + std::to_string(j) +
               " are not candidates");
}

}  // namespace broadphase::arrays
