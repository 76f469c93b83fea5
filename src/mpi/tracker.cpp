// Pairs over frames with a skin: the ghost lists and the shared list are
// kept between rebuilds (mpi.hpp, PairTracker).
#include <algorithm>
#include <broadphase/mpi.hpp>
#include <chrono>
#include <climits>
#include <cmath>
#include <string>

#include "pair_rule.hpp"

namespace broadphase::mpi {

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Bounds grown by the skin on every side (infinite sides stay infinite).
Aabb grown(const Aabb& b, double skin) {
  Aabb g;
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = b.lo[a] - skin;
    g.hi[a] = b.hi[a] + skin;
  }
  return g;
}

// True when `in` lies inside `out` (closed boxes).
bool inside(const Aabb& in, const Aabb& out) {
  return out.lo.x <= in.lo.x && in.hi.x <= out.hi.x && out.lo.y <= in.lo.y && in.hi.y <= out.hi.y &&
         out.lo.z <= in.lo.z && in.hi.z <= out.hi.z;
}

// What a refresh sends of an object whose copies it keeps: its shape and
// filter (64 bytes), without the id the receiver already knows.
struct Placed {
  Shape shape;
  Filter filter;
  friend bool operator==(const Placed&, const Placed&) = default;
};

Placed placed(const GhostRecord& r) { return {r.shape, r.filter}; }

}  // namespace

// What is kept between rebuilds. local holds this rank's objects at their
// own index [0, count), then the ghosts received [count, count + ghosts),
// then the other ranks' shared objects.
struct PairTracker::State {
  std::size_t count = 0;
  std::uint64_t cuts = 0;
  std::vector<std::uint32_t> ids;                 // this rank's ids at the rebuild
  std::vector<Aabb> fat;                          // their bounds grown by the skin
  std::vector<std::uint32_t> send_index;          // objects sent, in send order
  std::vector<int> send_dest;                     // and where
  std::vector<std::uint32_t> shared_index;        // this rank's objects in the shared list
  std::vector<int> shared_counts, shared_displs;  // bytes of Placed per rank
  std::size_t ghosts = 0, shared_others = 0, shared_total = 0;
  std::vector<GhostRecord> local;
  std::vector<std::uint32_t> local_ids;
  std::vector<std::uint8_t> alone;  // bounds stay inside this subdomain
  // The filters of `local` as the lean path's columns, filled when some
  // record's filter is not the default (`filtered`).
  std::vector<std::uint32_t> groups, masks;
  bool filtered = false;
  std::vector<Placed> shared_mine, shared_all;
  // The shape and filter each listed ghost had when it was last sent (what
  // its receiver holds), and the changed ones of a refresh with their ids.
  std::vector<Placed> sent;
  std::vector<GhostRecord> changed;
  std::vector<int> changed_dest;
  // The ghosts received, (id, slot in local) by id: where a changed one goes.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ghost_slot;
  // False from the start of a rebuild or refresh until it ends: a call
  // that failed in between leaves lists the ranks may not agree on, and the
  // next call rebuilds.
  bool valid = false;
};

PairTracker::PairTracker(Domain& domain, double skin)
    : domain_(domain), skin_(skin), state_(std::make_unique<State>()) {
  if (!(skin >= 0) || !std::isfinite(skin)) throw InvalidConfig("the skin must be finite and >= 0");
}

PairTracker::~PairTracker() = default;

bool PairTracker::beyond_skin(const Objects& objects) const {
  const State& st = *state_;
  if (!st.valid || objects.count != st.count || domain_.cuts() != st.cuts) return true;
  for (std::size_t i = 0; i < objects.count; ++i) {
    const Shape s = objects.shape(i);
    // An invalid shape rebuilds too: the rebuild names it.
    if (!is_valid(s) || !inside(bounds(s), st.fat[i])) return true;
  }
  return false;
}

bool PairTracker::take(const Objects& objects) {
  State& st = *state_;
  if (!st.valid || objects.count != st.count || domain_.cuts() != st.cuts) return true;
  // One pass: the copy a refresh needs (shape and filter: a filter that
  // changed travels as a changed shape does, and needs no rebuild since
  // the ghost lists depend on the bounds alone) and the skin check (a
  // rebuild overwrites the copy).
  bool beyond = false;
  for (std::size_t i = 0; i < objects.count; ++i) {
    const Shape s = objects.shape(i);
    st.local[i].shape = s;
    st.local[i].filter = detail::filter_at(objects.groups, objects.masks, i);
    beyond |= !is_valid(s) || !inside(bounds(s), st.fat[i]);
  }
  return beyond;
}

bool PairTracker::rebuild_due(const Objects& objects) {
  int mine = beyond_skin(objects) ? 1 : 0, any = 0;
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, domain_.comm());
  return any != 0;
}

void PairTracker::find_pairs(std::span<const std::uint32_t> ids, const Objects& objects,
                             std::vector<IdPair>& out) {
  const int rank = domain_.rank();
  domain_.agree(
      ids.size() != objects.count
          ? "rank " + std::to_string(rank) + ": " + std::to_string(ids.size()) + " ids for " +
                std::to_string(objects.count) + " objects"
          : detail::filter_columns_error(rank, objects.groups, objects.masks, objects.count));
  stats_ = Stats{};
  stats_.owned = objects.count;
  const Stats before = domain_.stats();
  const auto t0 = std::chrono::steady_clock::now();
  State& st = *state_;
  int mine = take(objects) || !std::equal(ids.begin(), ids.end(), st.ids.begin(), st.ids.end());
  int any = 0;
  MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, domain_.comm());
  if (any != 0)
    rebuild(ids, objects);
  else
    refresh();
  fill_filters(!objects.groups.empty());
  stats_.rebuilt = any != 0;
  stats_.ghosts = st.ghosts + st.shared_others;
  stats_.shared = st.shared_total;
  stats_.bytes_sent = domain_.stats().bytes_sent - before.bytes_sent;
  stats_.messages_sent = domain_.stats().messages_sent - before.messages_sent;
  if (!st.shared_index.empty() && domain_.size() > 1) {
    // The shared list goes to every other rank: records, then shapes with
    // their filters.
    const std::size_t each = stats_.rebuilt ? sizeof(GhostRecord) : sizeof(Placed);
    const auto others = static_cast<std::uint64_t>(domain_.size() - 1);
    stats_.bytes_sent += st.shared_index.size() * each * others;
    stats_.messages_sent += others;
  }
  stats_.exchange_seconds = since(t0);
  if (!domain_.options().local_pairs) return;

  // Local pairs, kept when this rank's subdomain holds max(lo_a, lo_b); a
  // pair with an object whose bounds stay inside the subdomain is this
  // rank's without a look (as in Domain::find_pairs).
  const auto t1 = std::chrono::steady_clock::now();
  std::string error;
  try {
    const std::size_t n = st.count + st.ghosts + st.shared_others;
    const GhostRecord* local = st.local.data();
    const std::uint32_t* local_id = st.local_ids.data();
    const std::uint8_t* alone = st.alone.data();
    const Partition& partition = domain_.partition();
    const std::size_t first = out.size();
    auto keep = [&](std::size_t i, std::size_t j) {
      return detail::keep_pair(partition, rank, local, local_id, i, j, (alone[i] | alone[j]) != 0,
                               out, error);
    };
    Objects view =
        n == 0 ? Objects{}
               : shapes_view(&local[0].shape, n, static_cast<std::ptrdiff_t>(sizeof(GhostRecord)));
    if (st.filtered && n > 0) {
      view.groups = {st.groups.data(), n};
      view.masks = {st.masks.data(), n};
    }
    const PairSink sink = [&](std::span<const IndexPair> chunk) {
      for (const IndexPair& p : chunk)
        if (!keep(p.i, p.j)) return false;
      return true;
    };
    // The one-shot lean path, not its PairTracker told what changed: at
    // scaled-even 1 024 000 on one rank (20 frames, one core) the frame
    // took 379 ms one-shot against 898 and 534 ms through the tracker
    // with skins of 4 and 10, whose rebuilds and renewals cost more than
    // the sphere kernel's pass.
    broadphase::find_pairs(view, sink);
    stats_.local_pairs = out.size() - first;
  } catch (const std::exception& e) {
    error = "rank " + std::to_string(rank) + ": " + e.what();
  }
  stats_.local_seconds = since(t1);
  domain_.agree(error);
}

void PairTracker::rebuild(std::span<const std::uint32_t> ids, const Objects& objects) {
  State& st = *state_;
  const int me = domain_.rank();
  std::string error;
  for (std::size_t i = 0; i < objects.count; ++i)
    if (!is_valid(objects.shape(i))) {
      error = "rank " + std::to_string(me) + ": object " + std::to_string(ids[i]) +
              " cannot be placed: its shape is not finite or has a negative extent";
      break;
    }
  st.valid = false;  // until this rebuild ends
  domain_.agree(error);
  ++rebuilds_;

  const Partition& partition = domain_.partition();
  const double margin = domain_.options().margin;
  const int max_ranks = domain_.options().max_ghost_ranks;
  const std::size_t n = objects.count;
  st.count = n;
  st.cuts = domain_.cuts();
  st.ids.assign(ids.begin(), ids.end());
  st.fat.resize(n);
  st.local.resize(n);
  st.alone.resize(n);
  st.send_index.clear();
  st.send_dest.clear();
  st.shared_index.clear();
  std::vector<int> reach;
  for (std::size_t i = 0; i < n; ++i) {
    const Shape s = objects.shape(i);
    const Aabb fat = grown(bounds(s), skin_);
    st.fat[i] = fat;
    st.local[i] = {s, ids[i], detail::filter_at(objects.groups, objects.masks, i)};
    const bool alone = partition.alone(me, fat, margin);
    st.alone[i] = alone ? 1 : 0;
    if (alone) continue;
    reach.clear();
    partition.ranks_meeting(fat, margin, reach);
    if (static_cast<int>(reach.size()) > max_ranks) {
      st.shared_index.push_back(static_cast<std::uint32_t>(i));
      continue;
    }
    for (int r : reach)
      if (r != me) {
        st.send_index.push_back(static_cast<std::uint32_t>(i));
        st.send_dest.push_back(r);
      }
  }

  // Ghosts, with their ids this time.
  std::vector<GhostRecord> records(st.send_index.size());
  for (std::size_t k = 0; k < records.size(); ++k) records[k] = st.local[st.send_index[k]];
  const std::vector<GhostRecord> received = domain_.exchange<GhostRecord>(records, st.send_dest);
  st.ghosts = received.size();
  st.local.insert(st.local.end(), received.begin(), received.end());
  st.sent.resize(records.size());
  for (std::size_t k = 0; k < records.size(); ++k) st.sent[k] = placed(records[k]);
  st.ghost_slot.resize(received.size());
  for (std::size_t g = 0; g < received.size(); ++g)
    st.ghost_slot[g] = {received[g].id, static_cast<std::uint32_t>(n + g)};
  std::sort(st.ghost_slot.begin(), st.ghost_slot.end());

  // The shared list: every rank's objects that reach many ranks.
  const int size = domain_.size();
  MPI_Comm comm = domain_.comm();
  records.resize(st.shared_index.size());
  for (std::size_t k = 0; k < records.size(); ++k) records[k] = st.local[st.shared_index[k]];
  const int bytes = static_cast<int>(records.size() * sizeof(GhostRecord));
  std::vector<int> counts(static_cast<std::size_t>(size)), displs(counts.size());
  MPI_Allgather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  long long total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = static_cast<int>(std::min<long long>(total, INT_MAX));
    total += counts[r];
  }
  domain_.agree(total > INT_MAX ? "the shared list of large objects exceeds 2 GB" : "");
  std::vector<GhostRecord> all(static_cast<std::size_t>(total) / sizeof(GhostRecord));
  MPI_Allgatherv(records.data(), bytes, MPI_BYTE, all.data(), counts.data(), displs.data(),
                 MPI_BYTE, comm);
  st.shared_counts.resize(counts.size());
  st.shared_displs.resize(counts.size());
  for (std::size_t r = 0; r < counts.size(); ++r) {
    st.shared_counts[r] =
        counts[r] / static_cast<int>(sizeof(GhostRecord)) * static_cast<int>(sizeof(Placed));
    st.shared_displs[r] =
        displs[r] / static_cast<int>(sizeof(GhostRecord)) * static_cast<int>(sizeof(Placed));
    if (static_cast<int>(r) == me) continue;  // this rank's are at their own index
    const auto* from = all.data() + displs[r] / static_cast<int>(sizeof(GhostRecord));
    st.local.insert(st.local.end(), from, from + counts[r] / static_cast<int>(sizeof(GhostRecord)));
  }
  st.shared_total = all.size();
  st.shared_others = all.size() - st.shared_index.size();
  st.alone.resize(st.local.size(), 0);
  st.local_ids.resize(st.local.size());
  for (std::size_t i = 0; i < st.local.size(); ++i) st.local_ids[i] = st.local[i].id;
  st.valid = true;
}

void PairTracker::refresh() {
  State& st = *state_;
  st.valid = false;  // until this refresh ends
  // Only the ghosts whose shape or filter changed since they were last
  // sent, each with its id (a rank's movers are a fifth of its objects in
  // the lab's scenes, and its quiet ghosts need nothing). They arrive by
  // source rank.
  st.changed.clear();
  st.changed_dest.clear();
  for (std::size_t k = 0; k < st.send_index.size(); ++k) {
    const GhostRecord& g = st.local[st.send_index[k]];
    if (placed(g) == st.sent[k]) continue;
    st.sent[k] = placed(g);
    st.changed.push_back(g);
    st.changed_dest.push_back(st.send_dest[k]);
  }
  const std::vector<GhostRecord> received =
      domain_.exchange<GhostRecord>(st.changed, st.changed_dest);
  std::string error;
  for (const GhostRecord& g : received) {
    const auto at = std::lower_bound(st.ghost_slot.begin(), st.ghost_slot.end(),
                                     std::pair<std::uint32_t, std::uint32_t>{g.id, 0});
    if (at == st.ghost_slot.end() || at->first != g.id) {
      error = "rank " + std::to_string(domain_.rank()) + ": a changed ghost, object " +
              std::to_string(g.id) + ", is not among the ghosts listed at the last rebuild";
      break;
    }
    st.local[at->second].shape = g.shape;
    st.local[at->second].filter = g.filter;
  }
  domain_.agree(error);
  auto place = [&](std::size_t slot, const Placed& p) {
    st.local[slot].shape = p.shape;
    st.local[slot].filter = p.filter;
  };

  const int me = domain_.rank();
  st.shared_mine.resize(st.shared_index.size());
  for (std::size_t k = 0; k < st.shared_mine.size(); ++k)
    st.shared_mine[k] = placed(st.local[st.shared_index[k]]);
  st.shared_all.resize(st.shared_total);
  MPI_Allgatherv(st.shared_mine.data(), static_cast<int>(st.shared_mine.size() * sizeof(Placed)),
                 MPI_BYTE, st.shared_all.data(), st.shared_counts.data(), st.shared_displs.data(),
                 MPI_BYTE, domain_.comm());
  std::size_t slot = st.count + st.ghosts;
  for (std::size_t r = 0; r < st.shared_counts.size(); ++r) {
    if (static_cast<int>(r) == me) continue;
    const std::size_t from = static_cast<std::size_t>(st.shared_displs[r]) / sizeof(Placed);
    const std::size_t k = static_cast<std::size_t>(st.shared_counts[r]) / sizeof(Placed);
    for (std::size_t q = 0; q < k; ++q) place(slot++, st.shared_all[from + q]);
  }
  st.valid = true;
}

void PairTracker::fill_filters(bool own) {
  // Columns for the lean path only when some record's filter is not the
  // default: this rank's objects when the caller gave columns, or a ghost
  // or shared object that came with one.
  State& st = *state_;
  const std::size_t n = st.local.size();
  bool filtered = own;
  for (std::size_t i = st.count; !filtered && i < n; ++i)
    filtered = !(st.local[i].filter == Filter{});
  st.filtered = filtered;
  if (!filtered) return;
  st.groups.resize(n);
  st.masks.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    st.groups[i] = st.local[i].filter.group;
    st.masks[i] = st.local[i].filter.mask;
  }
}

}  // namespace broadphase::mpi
