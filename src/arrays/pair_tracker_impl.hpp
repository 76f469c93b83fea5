// The tracker's state (PairTracker::Impl): the mode it is in and the parts
// it orchestrates, the index (tracker_index.hpp), movers mode (movers.hpp)
// and the quiet objects both share (quiet_set.hpp). Its calls are in
// pair_tracker.cpp, its ways into movers mode in movers.cpp. Private to
// the library.
#pragma once

#include <broadphase/arrays/arrays.hpp>
#include <broadphase/arrays/rays.hpp>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "calls.hpp"
#include "movers.hpp"
#include "quiet_set.hpp"
#include "tracker_index.hpp"
#include "tracker_tuning.hpp"

namespace broadphase::arrays {

// The lean path's private parts (src/arrays/).
using namespace detail;  // NOLINT(google-build-using-namespace)

struct PairTracker::Impl {
  // What the tracker holds between calls.
  enum class Mode : std::uint8_t {
    // Nothing: a first call, a new count, after clear(), or a call afresh
    // (with `afresh_left` calls afresh still to come).
    none,
    // The last call was afresh with no index, and kept its pairs (in
    // `quiet.hits`) and cells (in `movers.quiet_cells`), so that a call
    // listing its changes may enter movers mode from them.
    pending,
    // The index: fat boxes, candidate rows, renewals (`index`).
    index,
    // Movers mode (`movers`).
    movers,
  };

  ArrayOptions options;
  Mode mode = Mode::none;
  std::size_t count = 0;          // objects at the last call
  std::uint32_t afresh_left = 0;  // calls still to search afresh (see find_pairs)
  double skin_growth = 1;         // kSkinGrowth once the default skin was outrun
  // The index refused movers mode since its build (the quiet spheres did
  // not suit it): not tried again before a rebuild, a build is dear.
  bool movers_refused = false;
  std::uint32_t last_box = std::numeric_limits<std::uint32_t>::max();  // a box that kept it out
  QuietSet quiet;
  TrackerIndex index;
  Movers movers;
  // Rays (ray_caster): a grid over the objects of the last call, built at
  // the first cast after it.
  RayCaster rays;
  bool rays_current = false;

  // Whether the tracker holds an index or is in movers mode.
  bool built() const { return mode == Mode::index || mode == Mode::movers; }
  // The skin relative to the objects' size: the caller's, or the default
  // (kDefaultSkin, times skin_growth once it was outrun).
  double skin() const { return options.skin > 0 ? options.skin : skin_growth * kDefaultSkin; }
  // Builds the index afresh; movers mode and the quiet set go.
  void rebuild(const Objects& o);
  // Forgets everything but the options.
  void reset() {
    const ArrayOptions kept = options;
    *this = Impl{};
    options = kept;
  }
  // A call afresh where motion outran the skin (or one of the calls afresh
  // after it): the pairs when it searched afresh, holding nothing; nothing
  // when the set does not suit it.
  std::optional<ArrayCallStats> afresh_while_outrun(const Objects& objects, const PairSink& sink,
                                                    bool outran);
  // A call with no index yet on a set movers mode may take: the pairs,
  // found afresh and kept with their cells (Mode::pending); nothing when
  // the set does not suit it.
  std::optional<ArrayCallStats> afresh_pending(const Objects& objects, const PairSink& sink);

  // Partitions the objects by `changed` (those it does not list become
  // quiet) into movers mode, dropping the index; false, with nothing
  // changed, when the set does not suit it.
  bool enter_movers(const Objects& o, const std::vector<std::uint64_t>& changed);
  // Enters movers mode from the pairs of a pending call: the objects
  // `changed` lists become movers and their pairs go, the others are quiet
  // and sorted into cells of their own; false, with nothing changed, when
  // the set does not suit it.
  bool enter_from_pending(const Objects& o, const std::vector<std::uint64_t>& changed);
  // Whether movers mode can take this call (else the index is rebuilt).
  bool movers_suit(const Objects& o, const Changes& changes,
                   const std::vector<std::uint64_t>& changed) const;
  // A call in movers mode (Movers::call).
  ArrayCallStats movers_call(const Objects& o, const std::vector<std::uint64_t>& changed,
                             const PairSink& sink, bool check_listed) {
    return movers.call(o, changed, sink, check_listed, quiet, options);
  }
};

}  // namespace broadphase::arrays
