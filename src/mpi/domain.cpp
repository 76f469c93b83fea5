// The collective calls: agreement on errors, the all-to-all exchange, the
// weighted bisection, and pair finding with ghosts and the ownership rule.
#include <algorithm>
#include <broadphase/mpi.hpp>
#include <broadphase/registry.hpp>
#include <chrono>
#include <climits>
#include <cmath>
#include <exception>
#include <string>
#include <string_view>

#include "pair_rule.hpp"
#include "ray_caster.hpp"

namespace broadphase::mpi {

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

using Record = GhostRecord;

// Bins of one round of the bisection's histogram search. Eight rounds of 64
// bins narrow a bracket by 2^48, and the search stops earlier when the
// bracket holds no two doubles.
constexpr int kBins = 64;
constexpr int kRounds = 12;

// Edge j of the bracket [a, b] cut in kBins: one expression everywhere, so
// the bin of a coordinate and the edges agree exactly.
double edge(double a, double b, int j) { return j == kBins ? b : a + (b - a) * j / kBins; }

}  // namespace

void agree(MPI_Comm comm, const std::string& error) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const int mine = error.empty() ? size : rank;
  int lowest = size;
  MPI_Allreduce(&mine, &lowest, 1, MPI_INT, MPI_MIN, comm);
  if (lowest == size) return;
  int length = rank == lowest ? static_cast<int>(error.size()) : 0;
  MPI_Bcast(&length, 1, MPI_INT, lowest, comm);
  std::string message = rank == lowest ? error : std::string(static_cast<std::size_t>(length), ' ');
  MPI_Bcast(message.data(), length, MPI_CHAR, lowest, comm);
  throw MpiError(message);
}

void Domain::agree(const std::string& error) const { mpi::agree(comm_, error); }

Domain::Domain(MPI_Comm comm, const Aabb& world, Options options)
    : comm_(comm), world_(world), options_(std::move(options)) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(world.lo[a]) || !std::isfinite(world.hi[a]) || !(world.lo[a] < world.hi[a]))
      throw InvalidConfig("the world box must be finite and non-empty");
  if (!(options_.margin >= 0) || !std::isfinite(options_.margin))
    throw InvalidConfig("the margin must be finite and >= 0");
  if (!(options_.rebalance_threshold >= 1))
    throw InvalidConfig("the rebalance threshold must be >= 1");
  if (options_.max_ghost_ranks < 1) throw InvalidConfig("max_ghost_ranks must be >= 1");
  std::array<int, 3> dims = options_.dims;
  if (options_.decomposition == Decomposition::bisection) dims = {0, 0, 0};
  long given = 1;
  for (int d : dims) {
    if (d < 0) throw InvalidConfig("grid dims must be >= 0");
    if (d > 0) given *= d;
  }
  const bool free_dims = std::count(dims.begin(), dims.end(), 0) > 0;
  if ((free_dims && size_ % given != 0) || (!free_dims && given != size_))
    throw InvalidConfig("a grid of " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) +
                        "x" + std::to_string(dims[2]) + " does not fit " + std::to_string(size_) +
                        " ranks");
  MPI_Dims_create(size_, 3, dims.data());
  for (int a = 0; a < 3; ++a) {
    const double width = (world.hi[a] - world.lo[a]) / dims[static_cast<std::size_t>(a)];
    if (width < options_.margin)
      throw InvalidConfig("a grid of " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) +
                          "x" + std::to_string(dims[2]) +
                          " makes subdomains thinner than the margin " +
                          std::to_string(options_.margin));
  }
  options_.dims = dims;
  partition_ = Partition::grid(world_, dims);
  // The rays' structure is named here, on every rank alike, before any call.
  try {
    Config config;
    config.world = world_;
    make_structure(options_.ray_algo, config);
  } catch (const std::exception& e) {
    throw InvalidConfig("ray_algo '" + options_.ray_algo + "': " + e.what());
  }
}

std::vector<int> Domain::destinations(std::span<const Shape> shapes) const {
  std::vector<int> d(shapes.size());
  for (std::size_t i = 0; i < shapes.size(); ++i) d[i] = partition_.owner(shapes[i].center);
  return d;
}

void Domain::exchange_bytes(const void* data, std::size_t size, std::size_t count, const int* dest,
                            std::byte* (*resize)(void*, std::size_t), void* out) {
  const auto p = static_cast<std::size_t>(size_);
  const auto me = static_cast<std::size_t>(rank_);
  std::vector<long long> per(p, 0);
  std::string error;
  for (std::size_t i = 0; i < count; ++i) {
    if (dest[i] < 0 || dest[i] >= size_) {
      error = "rank " + std::to_string(rank_) + ": exchange to rank " + std::to_string(dest[i]) +
              ", outside [0, " + std::to_string(size_) + ")";
      break;
    }
    per[static_cast<std::size_t>(dest[i])] += static_cast<long long>(size);
  }
  long long at = 0;
  for (std::size_t r = 0; r < p; ++r) at += r == me ? 0 : per[r];
  if (at > INT_MAX || per[me] > INT_MAX)
    error = "rank " + std::to_string(rank_) + ": more than 2 GB to send";
  agree(error);
  // What stays on this rank does not go through MPI: it is copied once,
  // straight to its place in the result (the bulk of a migration, and of the
  // ghost exchange, which sends each object to its own rank too).
  std::vector<int> send_counts(p), send_displs(p), recv_counts(p), recv_displs(p);
  at = 0;
  for (std::size_t r = 0; r < p; ++r) {
    send_counts[r] = r == me ? 0 : static_cast<int>(per[r]);
    send_displs[r] = static_cast<int>(at);
    at += send_counts[r];
  }
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm_);
  long long total = 0;
  for (std::size_t r = 0; r < p; ++r) {
    recv_displs[r] = static_cast<int>(std::min<long long>(total, INT_MAX));
    total += r == me ? per[me] : recv_counts[r];
  }
  error.clear();
  if (total > INT_MAX) error = "rank " + std::to_string(rank_) + ": more than 2 GB to receive";
  agree(error);
  // Kept between calls and never shrunk: fresh pages cost a fault each
  // on the machines measured (docs/mpi.md).
  if (send_buffer_.size() < static_cast<std::size_t>(at))
    send_buffer_.resize(static_cast<std::size_t>(at));
  std::byte* send = send_buffer_.data();
  std::byte* recv = resize(out, static_cast<std::size_t>(total));
  std::vector<int> fill(send_displs);
  std::size_t self = static_cast<std::size_t>(recv_displs[me]);
  const auto* bytes = static_cast<const std::byte*>(data);
  for (std::size_t i = 0; i < count; ++i) {
    const auto r = static_cast<std::size_t>(dest[i]);
    if (r == me) {
      std::memcpy(recv + self, bytes + i * size, size);
      self += size;
    } else {
      std::memcpy(send + fill[r], bytes + i * size, size);
      fill[r] += static_cast<int>(size);
    }
  }
  MPI_Alltoallv(send, send_counts.data(), send_displs.data(), MPI_BYTE, recv, recv_counts.data(),
                recv_displs.data(), MPI_BYTE, comm_);
  for (std::size_t r = 0; r < p; ++r)
    if (r != me && send_counts[r] > 0) {
      stats_.bytes_sent += static_cast<std::uint64_t>(send_counts[r]);
      ++stats_.messages_sent;
    }
}

std::vector<double> Domain::weights_for(std::span<const Shape> shapes,
                                        std::span<const double> weights) const {
  std::string error;
  if (!weights.empty() && weights.size() != shapes.size())
    error = "rank " + std::to_string(rank_) + ": " + std::to_string(weights.size()) +
            " weights for " + std::to_string(shapes.size()) + " objects";
  for (std::size_t i = 0; error.empty() && i < weights.size(); ++i)
    if (!std::isfinite(weights[i]) || weights[i] < 0)
      error = "rank " + std::to_string(rank_) + ": weight " + std::to_string(i) + " is " +
              std::to_string(weights[i]) + " (finite and >= 0 wanted)";
  agree(error);
  if (!weights.empty()) return {weights.begin(), weights.end()};
  return std::vector<double>(shapes.size(), default_weight());
}

double Domain::default_weight() const {
  const bool measured =
      options_.balance_by == BalanceBy::measured && stats_.owned > 0 && stats_.local_seconds > 0;
  // Every rank must use one scale: a rank that has measured nothing yet
  // weighs its objects as the mean of the ranks that have.
  double each = measured ? stats_.local_seconds / static_cast<double>(stats_.owned) : 0;
  double mine[2] = {each, measured ? 1.0 : 0.0};
  double sum[2] = {0, 0};
  if (options_.balance_by == BalanceBy::measured)
    MPI_Allreduce(mine, sum, 2, MPI_DOUBLE, MPI_SUM, comm_);
  if (sum[1] == 0) return 1.0;
  if (!measured) each = sum[0] / sum[1];
  return each;
}

void Domain::balance(std::span<const Shape> shapes, std::span<const double> weights) {
  if (options_.decomposition != Decomposition::bisection) return;
  cut(shapes, weights_for(shapes, weights));
}

void Domain::cut(std::span<const Shape> shapes, const std::vector<double>& w) {
  // Open items of one level of the tree: ranks [r0, r1) in a finite box,
  // and where their node index goes in the parent.
  struct Item {
    int r0, r1;
    Aabb box;
    int parent;  // node index, -1 for the root
    bool right;
  };
  std::vector<Partition::Node> nodes;
  std::vector<Item> level{{0, size_, world_, -1, false}};
  std::vector<int> item_of(shapes.size(), 0);  // the open item each centre is in, -1: a leaf
  auto link = [&nodes](const Item& it, int child) {
    if (it.parent < 0) return;
    Partition::Node& p = nodes[static_cast<std::size_t>(it.parent)];
    (it.right ? p.right : p.left) = child;
  };
  while (!level.empty()) {
    // Leaves close at once; the others get a cut each from a joint search.
    std::vector<Item> open;
    std::vector<int> renumber(level.size(), -1);
    for (std::size_t k = 0; k < level.size(); ++k) {
      if (level[k].r1 - level[k].r0 == 1) {
        link(level[k], -1 - level[k].r0);
      } else {
        renumber[k] = static_cast<int>(open.size());
        open.push_back(level[k]);
      }
    }
    for (int& it : item_of)
      if (it >= 0) it = renumber[static_cast<std::size_t>(it)];
    if (open.empty()) break;
    const std::size_t m = open.size();
    std::vector<int> axis(m);
    std::vector<double> a(m), b(m), cut(m), target(m);
    std::vector<char> done(m, 0);
    std::string error;
    for (std::size_t k = 0; k < m; ++k) {
      const Aabb& box = open[k].box;
      int ax = 0;
      for (int c = 1; c < 3; ++c)
        if (box.hi[c] - box.lo[c] > box.hi[ax] - box.lo[ax]) ax = c;
      axis[k] = ax;
      a[k] = box.lo[ax] + options_.margin;
      b[k] = box.hi[ax] - options_.margin;
      if (a[k] > b[k])
        error = "bisection: " + std::to_string(open[k].r1 - open[k].r0) +
                " ranks do not fit in a box " + std::to_string(box.hi[ax] - box.lo[ax]) +
                " wide without a subdomain thinner than the margin " +
                std::to_string(options_.margin);
    }
    if (!error.empty()) throw MpiError(error);  // the same on every rank
    // Each round: per item, how many centres lie below a, in each bin of
    // [a, b), and at or above b; summed over the ranks.
    const std::size_t width = kBins + 2;
    // Sums of weights; sums of integer weights (counts) are exact in a
    // double up to 2^53, whatever order MPI adds them in.
    std::vector<double> local(m * width), global(m * width);
    for (int round = 0; round < kRounds; ++round) {
      std::fill(local.begin(), local.end(), 0);
      for (std::size_t i = 0; i < shapes.size(); ++i) {
        const int it = item_of[i];
        if (it < 0) continue;
        const auto k = static_cast<std::size_t>(it);
        const double x = shapes[i].center[axis[k]];
        std::size_t slot;
        if (x < a[k]) {
          slot = 0;
        } else if (x >= b[k]) {
          slot = kBins + 1;
        } else {
          int j = static_cast<int>((x - a[k]) / (b[k] - a[k]) * kBins);
          j = std::clamp(j, 0, kBins - 1);
          while (j > 0 && x < edge(a[k], b[k], j)) --j;
          while (j < kBins - 1 && x >= edge(a[k], b[k], j + 1)) ++j;
          slot = static_cast<std::size_t>(j) + 1;
        }
        local[k * width + slot] += w[i];
      }
      MPI_Allreduce(local.data(), global.data(), static_cast<int>(local.size()), MPI_DOUBLE,
                    MPI_SUM, comm_);
      bool all_done = true;
      for (std::size_t k = 0; k < m; ++k) {
        if (done[k]) continue;
        const double* h = &global[k * width];
        double total = 0;
        for (std::size_t s = 0; s < width; ++s) total += h[s];
        const int ranks = open[k].r1 - open[k].r0;
        target[k] = total * (ranks / 2) / ranks;
        // below[j]: centres below edge j.
        double below = h[0];
        int j = 0;
        if (below >= target[k]) {
          cut[k] = a[k];
          done[k] = 1;
          continue;
        }
        while (j < kBins && below + h[j + 1] < target[k]) {
          below += h[j + 1];
          ++j;
        }
        if (j == kBins) {
          cut[k] = b[k];
          done[k] = 1;
          continue;
        }
        // The target falls in bin j: [edge j, edge j+1).
        const double lo = edge(a[k], b[k], j), hi = edge(a[k], b[k], j + 1);
        const double above = below + h[j + 1];
        if (round == kRounds - 1 || std::nextafter(lo, hi) >= hi) {
          cut[k] = target[k] - below <= above - target[k] ? lo : hi;
          done[k] = 1;
          continue;
        }
        a[k] = lo;
        b[k] = hi;
        all_done = false;
      }
      if (all_done) break;
    }
    std::vector<Item> next;
    for (std::size_t k = 0; k < m; ++k) {
      const Item& it = open[k];
      const int index = static_cast<int>(nodes.size());
      nodes.push_back({axis[k], cut[k], 0, 0});
      link(it, index);
      const int half = it.r0 + (it.r1 - it.r0) / 2;
      Aabb lbox = it.box, rbox = it.box;
      lbox.hi[axis[k]] = cut[k];
      rbox.lo[axis[k]] = cut[k];
      next.push_back({it.r0, half, lbox, index, false});
      next.push_back({half, it.r1, rbox, index, true});
    }
    for (std::size_t i = 0; i < shapes.size(); ++i) {
      const int it = item_of[i];
      if (it < 0) continue;
      const auto k = static_cast<std::size_t>(it);
      item_of[i] = static_cast<int>(2 * k) + (shapes[i].center[axis[k]] < cut[k] ? 0 : 1);
    }
    level = std::move(next);
  }
  partition_ = Partition(std::move(nodes), size_);
  ++cuts_;
}

bool Domain::rebalance(std::span<const Shape> shapes, std::span<const double> weights) {
  if (options_.decomposition != Decomposition::bisection) return false;
  const std::vector<double> w = weights_for(shapes, weights);
  double mine = 0, heaviest = 0;
  for (double x : w) {
    mine += x;
    heaviest = std::max(heaviest, x);
  }
  if (!due(mine, heaviest)) return false;
  cut(shapes, w);
  return true;
}

bool Domain::rebalance(const Objects& objects) {
  if (options_.decomposition != Decomposition::bisection) return false;
  // Every object weighs the same here: no vector of weights unless a cut
  // is due.
  const double each = default_weight();
  if (!due(each * static_cast<double>(objects.count), objects.count > 0 ? each : 0.0)) return false;
  std::vector<Shape> shapes(objects.count);
  for (std::size_t i = 0; i < objects.count; ++i) shapes[i] = objects.shape(i);
  cut(shapes, std::vector<double>(objects.count, each));
  return true;
}

bool Domain::due(double mine, double heaviest) const {
  // The most loaded rank's weight and the heaviest object, in one reduction.
  double local_max[2] = {mine, heaviest}, global_max[2] = {0, 0}, sum = 0;
  MPI_Allreduce(local_max, global_max, 2, MPI_DOUBLE, MPI_MAX, comm_);
  MPI_Allreduce(&mine, &sum, 1, MPI_DOUBLE, MPI_SUM, comm_);
  const double most = global_max[0], top = global_max[1];
  const double mean = sum / size_;
  // One object above the mean is the best cuts can do (8 objects on 8
  // ranks, objects on one point): no rebuild for that.
  return !(sum == 0 || most <= mean * options_.rebalance_threshold || most <= mean + top);
}

Objects shapes_view(const Shape* first, std::size_t count, std::ptrdiff_t stride) {
  Objects view;
  view.count = count;
  if (first == nullptr || count == 0) {
    view.count = 0;
    return view;
  }
  view.x = {&first->center.x, stride, Real::f64};
  view.y = {&first->center.y, stride, Real::f64};
  view.z = {&first->center.z, stride, Real::f64};
  view.radius = {&first->half.x, stride, Real::f64};  // a sphere's radius is its half.x
  view.half_x = view.radius;
  view.half_y = {&first->half.y, stride, Real::f64};
  view.half_z = {&first->half.z, stride, Real::f64};
  static_assert(sizeof(ShapeKind) == 1 && static_cast<int>(ShapeKind::sphere) == 0 &&
                static_cast<int>(ShapeKind::box) == 1);
  view.kind = reinterpret_cast<const std::uint8_t*>(&first->kind);
  view.kind_stride = stride;
  return view;
}

GhostRecord* Domain::grow_local(std::size_t used, std::size_t count) {
  if (local_.size() < used + count) local_.resize(used + count);
  if (local_ids_.size() < local_.size()) local_ids_.resize(local_.size());
  return local_.data() + used;
}

void Domain::find_pairs(std::span<const std::uint32_t> ids, const Objects& objects,
                        std::vector<IdPair>& out) {
  agree(ids.size() != objects.count
            ? "rank " + std::to_string(rank_) + ": " + std::to_string(ids.size()) + " ids for " +
                  std::to_string(objects.count) + " objects"
            : detail::filter_columns_error(rank_, objects.groups, objects.masks, objects.count));
  find_pairs_of(
      ids, objects.count, [&](std::size_t i) { return objects.shape(i); }, objects.groups,
      objects.masks, out);
}

void Domain::find_pairs(std::span<const std::uint32_t> ids, std::span<const Shape> shapes,
                        std::vector<IdPair>& out) {
  find_pairs(ids, shapes, {}, {}, out);
}

void Domain::find_pairs(std::span<const std::uint32_t> ids, std::span<const Shape> shapes,
                        std::span<const std::uint32_t> groups, std::span<const std::uint32_t> masks,
                        std::vector<IdPair>& out) {
  agree(ids.size() != shapes.size()
            ? "rank " + std::to_string(rank_) + ": " + std::to_string(ids.size()) + " ids for " +
                  std::to_string(shapes.size()) + " shapes"
            : detail::filter_columns_error(rank_, groups, masks, shapes.size()));
  find_pairs_of(
      ids, shapes.size(), [&](std::size_t i) { return shapes[i]; }, groups, masks, out);
}

template <class ShapeAt>
void Domain::find_pairs_of(std::span<const std::uint32_t> ids, std::size_t count, ShapeAt shape_at,
                           std::span<const std::uint32_t> groups,
                           std::span<const std::uint32_t> masks, std::vector<IdPair>& out) {
  stats_ = Stats{};
  stats_.owned = count;
  const auto t0 = std::chrono::steady_clock::now();
  std::string error;

  // Ghosts: each object to every rank its bounds reach, or to everyone. An
  // object whose bounds, grown by the margin, stay inside this rank's
  // subdomain reaches no other rank: it is written straight to local_ (the
  // comparisons are ranks_meeting's, against the cuts that bound this
  // subdomain), with no search of the cut tree and no exchange. Those come
  // first in local_, and every pair with one of them is this rank's: when
  // a's bounds lie in the subdomain and b's bounds meet a's, then per axis
  // lo_a <= max(lo_a, lo_b) <= hi_a, inside the subdomain.
  const Aabb& region = partition_.region(rank_);
  const double margin = options_.margin;
  sent_.clear();
  dest_.clear();
  shared_mine_.clear();
  std::vector<Record> near_self;  // this rank's objects that reach others too
  std::vector<int> reach;
  std::size_t used = 0;
  Record* inner = grow_local(0, count);
  for (std::size_t i = 0; i < count; ++i) {
    const Shape s = shape_at(i);
    if (!is_valid(s)) {
      error = "rank " + std::to_string(rank_) + ": object " + std::to_string(ids[i]) +
              " cannot be placed: its shape is not finite or has a negative extent";
      break;
    }
    const Aabb box = bounds(s);
    const Record record{s, ids[i], detail::filter_at(groups, masks, i)};
    if (partition_.alone(rank_, box, margin)) {
      inner[used] = record;
      local_ids_[used] = ids[i];
      ++used;
      continue;
    }
    reach.clear();
    partition_.ranks_meeting(box, margin, reach);
    if (static_cast<int>(reach.size()) > options_.max_ghost_ranks) {
      shared_mine_.push_back(record);
      continue;
    }
    for (int r : reach)
      if (r == rank_) {
        near_self.push_back(record);
      } else {
        sent_.push_back(record);
        dest_.push_back(r);
      }
  }
  agree(error);
  const std::size_t anchored = used;
  std::copy(near_self.begin(), near_self.end(), grow_local(used, near_self.size()));
  used += near_self.size();
  {
    // Received ghosts go after this rank's own objects.
    std::vector<Record> received;
    exchange<Record>(sent_, dest_).swap(received);
    stats_.ghosts = received.size();
    std::copy(received.begin(), received.end(), grow_local(used, received.size()));
    used += received.size();
  }
  // The shared list: every rank's big objects to every rank.
  const int mine = static_cast<int>(shared_mine_.size() * sizeof(Record));
  std::vector<int> counts(static_cast<std::size_t>(size_)), displs(counts.size());
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_);
  long long total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = static_cast<int>(total);
    total += counts[r];
  }
  agree(total > INT_MAX ? "the shared list of large objects exceeds 2 GB" : "");
  const std::size_t before = used;
  used += static_cast<std::size_t>(total) / sizeof(Record);
  MPI_Allgatherv(shared_mine_.data(), mine, MPI_BYTE, grow_local(before, used - before),
                 counts.data(), displs.data(), MPI_BYTE, comm_);
  // The lean path is given filter columns only when some record here has
  // a filter other than the default: this rank's own objects when the
  // caller gave columns, or a ghost or shared object that came with one
  // (a rank without columns of its own may still hold filtered ghosts).
  bool filtered = !groups.empty();
  for (std::size_t i = anchored; i < used; ++i) {
    local_ids_[i] = local_[i].id;
    filtered = filtered || !(local_[i].filter == Filter{});
  }
  if (filtered) {
    local_groups_.resize(used);
    local_masks_.resize(used);
    for (std::size_t i = 0; i < used; ++i) {
      local_groups_[i] = local_[i].filter.group;
      local_masks_[i] = local_[i].filter.mask;
    }
  }
  local_used_ = used;
  stats_.shared = static_cast<std::uint64_t>(total) / sizeof(Record);
  stats_.ghosts += stats_.shared - shared_mine_.size();
  if (mine > 0) {
    stats_.bytes_sent += static_cast<std::uint64_t>(mine) * static_cast<std::uint64_t>(size_ - 1);
    stats_.messages_sent += static_cast<std::uint64_t>(size_ - 1);
  }
  stats_.exchange_seconds = since(t0);

  // Local pairs, kept when this rank's subdomain holds max(lo_a, lo_b).
  const auto t1 = std::chrono::steady_clock::now();
  if (!options_.local_pairs) return;
  try {
    const Record* local = local_.data();
    const std::uint32_t* local_id = local_ids_.data();
    const std::size_t first = out.size();
    // Keeps pair (i, j) of `local` when this rank's subdomain holds
    // max(lo_i, lo_j), known without a look when either lies in the
    // subdomain (above); false stops (an id seen twice).
    auto keep = [&](std::size_t i, std::size_t j) {
      return detail::keep_pair(partition_, rank_, local, local_id, i, j,
                               i < anchored || j < anchored, out, error);
    };
    if (options_.algo == std::string_view(kLeanPath)) {
      // The lean path reads the records in place (arrays.hpp): no
      // structure is built and no copy made.
      // (A rank with nothing local has no record to point into.)
      Objects view = used == 0 ? Objects{}
                               : shapes_view(&local[0].shape, used,
                                             static_cast<std::ptrdiff_t>(sizeof(Record)));
      if (filtered && used > 0) {
        view.groups = {local_groups_.data(), used};
        view.masks = {local_masks_.data(), used};
      }
      broadphase::find_pairs(view, [&](std::span<const IndexPair> chunk) {
        for (const IndexPair& p : chunk)
          if (!keep(p.i, p.j)) return false;
        return true;
      });
    } else {
      Config config;
      config.world = world_;
      Aabb clipped;
      bool usable = true;
      for (int a = 0; a < 3; ++a) {
        clipped.lo[a] = std::max(region.lo[a], world_.lo[a]);
        clipped.hi[a] = std::min(region.hi[a], world_.hi[a]);
        usable = usable && clipped.lo[a] < clipped.hi[a];
      }
      if (usable) config.world = clipped;
      config.expected_objects = used;
      auto structure = make_structure(options_.algo, config);
      // The filters inside the structure's own walk (set_filter when not
      // the default), as on one process.
      for (std::size_t i = 0; i < used; ++i)
        structure->insert(local[i].shape, i, Motion::dynamic, local[i].filter);
      std::vector<HandlePair> pairs;
      structure->find_pairs(pairs);
      for (const HandlePair& p : pairs)
        if (!keep(static_cast<std::size_t>(structure->user_data(p.a)),
                  static_cast<std::size_t>(structure->user_data(p.b))))
          break;
    }
    stats_.local_pairs = out.size() - first;
  } catch (const std::exception& e) {
    error = "rank " + std::to_string(rank_) + ": " + e.what();
  }
  stats_.local_seconds = since(t1);
  agree(error);
}

}  // namespace broadphase::mpi
