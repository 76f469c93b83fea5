// The lean tracker's tuned constants, each with the measurement behind it,
// and the bit helpers its parts share. Private to the library.
#pragma once

#include <broadphase/arrays/arrays.hpp>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sphere_kernel.hpp"

namespace broadphase::arrays::detail {

// Candidate entries: the partner's index, and in the top bit whether the
// pair overlapped at the last call (valid while neither object changes).
constexpr std::uint32_t kOverlapBit = 0x80000000u;
constexpr std::uint32_t kIndexMask = 0x7FFFFFFFu;
constexpr std::size_t kMaxTracked = kIndexMask;

// When more than this fraction of the objects leave in one call, a rebuild
// is cheaper than renewing each (a renewal queries the grid on every level,
// several times the work of one object's probe in a build).
constexpr double kRebuildFraction = 0.25;
// The default skin widens once, by this factor, at a call where more than
// one changed object in kSkinGrowShare left its fat box (the motion
// outruns the skin, beyond the waves of renewals of steady movers): the
// index is then built again with the wider skin. Alternated with the
// build before on one core (20 000 objects, 20% movers, 60 calls,
// docs/arrays.md, "The tracker's index path"): boxes 6.4-8.3 -> 1.4-1.5 ms a call,
// half-boxes 3.9-4.0 -> 1.0-1.2, box-decades 33-34 -> 7.7-9.1. Widened
// at renewals alone, without the build, the boxes not renewed kept the
// narrow skin: boxes 3.2 ms, box-decades 16. With one in four, city
// widened too (a wave of 29% at its third call) and got slower, 1.2-1.9
// -> 1.5-2.3 ms.
constexpr double kDefaultSkin = 0.25;  // ArrayOptions::skin's default
constexpr double kSkinGrowth = 4;
constexpr std::size_t kSkinGrowShare = 2;
// Afresh only in cells this crowded at most (the largest, over the
// kernel's grids, of the spheres sharing a sphere's cell, itself included,
// on average): all-moving 20 000 gives 1.3, scaled-even 1 024 000 at most
// 4.4; the study's scenes at 6 400, where the index is faster, 8.5 and 15.
constexpr double kAfreshCrowd = 5;
constexpr std::uint32_t kAfreshCalls = 8;
// Compaction folds the loose pairs into the rows once this fraction of the
// objects is renewed, or the loose pairs (8 bytes each) take more than half
// the memory of the rows' partners and the quiet pairs (docs/arrays.md).
constexpr double kCompactFraction = 0.1;
// A renewed object's box reaches ahead by this times its last displacement,
// if that was at most kAheadSkins skins. Renewals over 16 frames at
// scaled-even 1 024 000: 305 543 with no reach, 209 304 with 1, 160 022
// with 2, 160 020 with 3; own memory 88, 89, 81, 82 B/object.
constexpr double kAheadFactor = 2.0;
constexpr double kAheadSkins = 4.0;
// An object's skin is at least this share of the skin relative to its own
// size (the global skin is relative to the median size): objects much larger
// than the median then keep their fat box longer (their renewals query every
// finer level, the costliest).
constexpr double kOwnSkinShare = 0.25;
// A call copies the shapes into the rows' order when at least one object in
// this many changed.
constexpr std::size_t kGatherShare = 8;
// Objects become quiet after this many calls in a row that listed their
// changes (at first; see QuietSet::after).
constexpr std::uint32_t kQuietAfter = 2;
// The scan asks for the shapes of the partners this many rows ahead.
constexpr std::size_t kPrefetchRows = 8;
// Movers mode (Movers, movers.hpp): taken when the objects listed at
// a partition are at most one in kMoversShare, all objects are spheres and
// the quiet ones are at most this crowded (SphereCells::crowd); left for a
// new partition when one quiet object in kWokenShare has been changed since,
// or when, kMoversPatience calls after it, the movers are more than twice
// the objects listed in a call (many stopped).
constexpr std::size_t kMoversShare = 4;
// As crowded as the sphere kernel takes (SphereCells::kMaxCrowd). At 5,
// crowded sets stayed on the index; measured on one core, 20% movers,
// index -> movers mode (median call): decades 20 000 38.4 -> 2.8 ms,
// clusters 3.6 -> 0.9, coincident 2.4 -> 0.6, outside 3.9 -> 1.1, study
// uneven 6 400 1.41 -> 1.03, scaled-uneven 1 024 000 580 -> 306 ms and
// 257 -> 125 B/object; the others do not change.
constexpr double kMoversCrowd = SphereCells::kMaxCrowd;
// ArrayOptions::spare_bytes by default.
constexpr std::size_t kSpareBytes = std::size_t{16} << 20;
constexpr std::size_t kWokenShare = 8;
// A mover's list of quiet candidates reaches this many calls of its last
// speed past it, at least kListSkinShare of its radius, at most four radii
// plus kListSkinQuiet of the largest quiet radius (see MoverList). A
// renewal (a probe of the quiet grids, 60 tests and most of a microsecond
// at scaled-even 1 024 000) costs a hundred list tests: at 3 calls, 15 000
// to 67 000 movers of 204 800 renewed a call over 40 calls there, the
// median call 88-94 ms; at 12, 5 000-22 000 and 80-83 ms, for 2.3 bytes an
// object more (at 20: 80 ms, 4.6 more). The cap was four radii: a small
// fast mover renewed every call, though among quiet spheres far larger
// than it a longer skin adds few candidates.
constexpr double kListSkinCalls = 12;
constexpr double kListSkinShare = 0.25;
constexpr double kListSkinQuiet = 0.5;
// A new list's centre is put ahead of its mover, along the way it went
// since its last list, by this many times its skin beyond kListSkinShare
// of its radius (at most the skin): a mover in steady motion then lasts
// about twice as many calls on one list of the same reach, and a slow one
// (a skin of kListSkinShare) stays centred. A renewal took about 1.25 us
// at scaled-even 1 024 000. Alternated on one core against centred lists
// (the same pairs): there, 60 calls, median 72.4-73.2 -> 63.9-67.1 ms,
// mean 74.5-76.9 -> 68.0-71.4; study even and uneven 6 400 4-5% faster;
// a random walk the same within 1.2% (docs/arrays.md, "Movers mode"). At 1, 2,
// 4 and 8 times, the million's mean 71.7, 70.9, 68.0 ms and 1% over 4's.
constexpr double kListAhead = 4;
constexpr std::size_t kCoarseCellsPerObject = 1;
constexpr double kCoarseCrowd = 8;
constexpr double kCoarseSpread = 2;
constexpr std::uint32_t kMoversPatience = 8;

inline bool test_bit(const std::vector<std::uint64_t>& bits, std::uint32_t k) {
  return (bits[k >> 6] >> (k & 63)) & 1;
}
inline void set_bit(std::vector<std::uint64_t>& bits, std::uint32_t k) {
  bits[k >> 6] |= std::uint64_t{1} << (k & 63);
}

// Half of ArrayOptions::spare_bytes: for the quiet pairs as IndexPairs,
// and for the movers' lists in sets where the quiet pairs are many.
inline std::size_t spare_half(const ArrayOptions& options) {
  return (options.spare_bytes > 0 ? options.spare_bytes : kSpareBytes) / 2;
}

}  // namespace broadphase::arrays::detail
