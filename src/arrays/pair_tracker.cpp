// The lean path's tracker (PairTracker, arrays.hpp): which mode a call
// takes (the index, tracker_index.hpp; movers mode, movers.hpp; a search
// afresh, holding nothing) and the call on the index: renewals, the scan
// of the candidate rows with exact tests read from the caller's data, the
// quiet pairs handed over as they stand (quiet_set.hpp).
#include "pair_tracker_impl.hpp"

namespace broadphase::arrays {

void PairTracker::Impl::rebuild(const Objects& o) {
  movers = Movers{};
  movers_refused = false;
  index.build(o, skin(), thread_count(options.threads));
  quiet.clear();
  count = o.count;
  mode = Mode::index;
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
std::optional<ArrayCallStats> PairTracker::Impl::afresh_while_outrun(const Objects& objects,
                                                                     const PairSink& sink,
                                                                     bool outran) {
  detail::SphereCells cells;
  if (cells.build(objects) && cells.crowd() <= kAfreshCrowd) {
    const std::uint32_t left = outran ? kAfreshCalls : afresh_left - 1;
    reset();
    afresh_left = left;
    ArrayCallStats stats =
        cell_pairs(cells, sink, options, nullptr, detail::PairFilterColumns::of(objects));
    stats.afresh = true;
    return stats;
  }
  afresh_left = 0;
  return std::nullopt;
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
std::optional<ArrayCallStats> PairTracker::Impl::afresh_pending(const Objects& objects,
                                                                const PairSink& sink) {
  detail::SphereCells cells;
  if (build_quiet_cells(cells, objects, {})) {
    const std::uint32_t quiet_after = quiet.after;
    reset();
    // Reserved, not written: untouched pages cost nothing. Grown by
    // doubling, the 2.58 million pairs of scaled-even 1 024 000 took
    // 15-20 ms more in copies and fresh pages.
    std::vector<IndexPair> all;
    all.reserve(std::min<std::size_t>(4 * objects.count, std::size_t{1} << 26));
    ArrayCallStats stats =
        cell_pairs(cells, sink, options, &all, detail::PairFilterColumns::of(objects));
    quiet.after = quiet_after;
    mode = Mode::pending;
    count = objects.count;
    if (!stats.stopped) {  // (a sink that stopped early saw only some)
      quiet.hits.assign(all, objects.count, spare_half(options));
      movers.quiet_cells = std::move(cells);
    }
    stats.afresh = true;
    return stats;
  }
  return std::nullopt;
}

PairTracker::PairTracker(const ArrayOptions& options) : impl_(std::make_unique<Impl>()) {
  options.check();
  impl_->options = options;
}
PairTracker::~PairTracker() = default;
PairTracker::PairTracker(PairTracker&&) noexcept = default;
PairTracker& PairTracker::operator=(PairTracker&&) noexcept = default;

ArrayCallStats PairTracker::find_pairs(const Objects& objects, const PairSink& sink,
                                       const Changes& changes) {
  Impl& im = *impl_;
  im.rays_current = false;
  // Everything that can throw on bad input runs before the tracker changes.
  // A movers call reads only the objects listed (and movers whose values
  // it checked when they were listed): it checks the listed ones alone,
  // as it reads them (Impl::movers_call).
  // Any other call, and a movers call that partitions again or leaves the
  // mode, checks every value first (check_all).
  const bool listed_only =
      !changes.all && im.mode == Impl::Mode::movers && objects.count == im.count;
  bool checked = !listed_only;
  auto check_all = [&] {
    if (!checked) check_objects(objects);
    checked = true;
  };
  if (!listed_only) check_objects(objects);
  detail::check_filter_columns(objects, "objects");
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
  bool rebuild = !im.built() || objects.count != im.count;
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
  if (im.mode == Impl::Mode::pending && !changes.all && objects.count == im.count &&
      (im.movers.quiet_cells.size() == objects.count ? im.enter_from_pending(objects, changed)
                                                     : im.enter_movers(objects, changed))) {
    stats = im.movers_call(objects, changed, sink, false);
    stats.compacted = true;
    return stats;
  }
  // Movers mode: a call that lists its changes on the same spheres stays in
  // it (after a new partition if due); any other leaves it for the index.
  if (im.mode == Impl::Mode::movers) {
    bool take = im.movers_suit(objects, changes, changed);
    bool partitioned = false;
    if (take && im.movers.stale(im.quiet, changed, changed_count)) {
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
  TrackerIndex::Leavers leave;
  bool outran = false;  // a rebuild is due because objects left their boxes
  if (!rebuild) {
    leave = im.index.leavers(objects, changes.all, changed, changed_count, im.quiet);
    rebuild = static_cast<double>(leave.renew.size()) > kRebuildFraction * static_cast<double>(n);
    outran = rebuild;
  }
  if (outran || (rebuild && im.afresh_left > 0))
    if (auto afresh = im.afresh_while_outrun(objects, sink, outran)) return *afresh;
  if (rebuild && im.mode != Impl::Mode::pending)
    if (auto afresh = im.afresh_pending(objects, sink)) return *afresh;
  // Objects that did not change in this call while their candidates are
  // still scanned become quiet, when they are many (a pass over the rows).
  if (changes.all) {
    im.quiet.listed_calls = 0;
    if (im.quiet.count > 0) im.quiet.after = std::min<std::uint32_t>(im.quiet.after * 4, 1u << 20);
  } else {
    ++im.quiet.listed_calls;
  }
  const bool bits_hold =
      im.built() && !im.index.fresh && !changes.all && im.quiet.listed_calls >= im.quiet.after;
  auto partition_pays = [&] {
    return bits_hold && (n - im.quiet.count) - (changed_count - leave.quiet_changed) > n / 8;
  };
  // The default skin outrun by a share of the changed objects at one call:
  // built again, once, with a wider one (kSkinGrowth). A skin the caller
  // chose stays as it is.
  if (!rebuild && im.built() && im.options.skin <= 0 && im.skin_growth == 1 &&
      leave.renew.size() * kSkinGrowShare > changed_count) {
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
    if ((partition_now || (bits_hold && im.quiet.count > 0 && !im.movers_refused)) &&
        im.enter_movers(objects, changed)) {
      stats = im.movers_call(objects, changed, sink, false);
      stats.compacted = true;
      return stats;
    }
    if (!leave.renew.empty()) {
      im.index.renew(leave.renew, im.quiet);
      stats.renewed = leave.left;
      stats.woken = leave.quiet_changed;
    }
    if (partition_now || (!leave.renew.empty() && im.index.wants_compaction(im.quiet))) {
      im.index.compact(objects, bits_hold ? &changed : nullptr, im.quiet, spare_half(im.options));
      stats.compacted = true;
    }
  }
  im.index.scan(objects, changes.all, changed, changed_count, im.quiet, im.options, sink, stats);
  im.index.fresh = stats.stopped;
  stats.quiet = im.quiet.count;
  return stats;
}

ArrayCallStats PairTracker::find_pairs(const Objects& objects, std::vector<IndexPair>& out,
                                       const Changes& changes) {
  return find_pairs(objects, append_to(out), changes);
}

std::size_t PairTracker::memory_bytes() const {
  const Impl& im = *impl_;
  return sizeof(Impl) + im.quiet.memory_bytes() + im.index.memory_bytes() +
         im.movers.memory_bytes() + im.rays.memory_bytes();
}

const RayCaster& PairTracker::ray_caster(const Objects& objects) {
  Impl& im = *impl_;
  if (!im.rays_current) {
    im.rays.build(objects);
    im.rays_current = true;
  } else if (objects.count != im.rays.size()) {
    throw std::invalid_argument(
        "broadphase: PairTracker::ray_caster: " + std::to_string(objects.count) +
        " objects, the last call had " + std::to_string(im.rays.size()) +
        " (rays are cast into the objects of the last find_pairs call)");
  }
  return im.rays;
}

void PairTracker::clear() { impl_->reset(); }

void PairTracker::validate(const Objects& objects) const {
  const Impl& im = *impl_;
  auto fail = [](const std::string& why) { throw std::logic_error("PairTracker: " + why); };
  if (!im.built()) return;
  if (im.count != objects.count) fail("count differs from the last call's objects");
  if (im.mode == Impl::Mode::movers) {
    im.movers.check(objects, im.quiet);
    return;
  }
  if (im.index.count() != im.count) fail("one fat box and place per object");
  im.index.check(objects, im.quiet);
}

}  // namespace broadphase::arrays
