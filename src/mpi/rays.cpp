// Rays over the ranks: every rank casts the whole batch against its own
// objects, then the closest hits are reduced by (t, id), the all-hits rows
// gathered, the any-hit bits or-ed.
#include <algorithm>
#include <broadphase/mpi.hpp>
#include <broadphase/registry.hpp>
#include <chrono>
#include <climits>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

#include "ray_caster.hpp"

namespace broadphase::mpi {

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// A digest of a batch of rays, over the bits of every field (not the
// struct's bytes: Ray has padding), so that the ranks can check that they
// pass the same batch.
std::uint64_t batch_digest(std::span<const Ray> rays) {
  std::uint64_t h = mix(rays.size());
  auto add = [&](double v) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    h = mix(h ^ bits);
  };
  for (const Ray& r : rays) {
    for (int a = 0; a < 3; ++a) add(r.origin[a]);
    for (int a = 0; a < 3; ++a) add(r.dir[a]);
    add(r.tmax);
    h = mix(h ^ r.mask);
  }
  return h;
}

// The contract's closest-hit order over ids: a hit before no hit, then the
// smaller t, then the smaller id. A total order on hits (t is never NaN),
// so a reduction by it gives the same answer in any grouping.
bool before(const IdHit& a, const IdHit& b) {
  if (a.hit != b.hit) return a.hit;
  return a.t < b.t || (a.t == b.t && a.id < b.id);
}

void closest_op(void* in, void* inout, int* len, MPI_Datatype*) {
  const auto* a = static_cast<const IdHit*>(in);
  auto* b = static_cast<IdHit*>(inout);
  for (int i = 0; i < *len; ++i)
    if (before(a[i], b[i])) b[i] = a[i];
}

// One hit as it is gathered: the ray it belongs to travels with it.
struct WireHit {
  double t;
  std::uint32_t id;
  std::uint32_t ray;
};
static_assert(sizeof(WireHit) == 16 && sizeof(IdHit) == 16);

// A datatype of `bytes` contiguous bytes, freed with the scope.
class Bytes {
 public:
  explicit Bytes(int bytes) {
    MPI_Type_contiguous(bytes, MPI_BYTE, &type_);
    MPI_Type_commit(&type_);
  }
  ~Bytes() { MPI_Type_free(&type_); }
  Bytes(const Bytes&) = delete;
  Bytes& operator=(const Bytes&) = delete;
  MPI_Datatype type() const { return type_; }

 private:
  MPI_Datatype type_;
};

}  // namespace

Domain::~Domain() = default;
Domain::Domain(Domain&&) noexcept = default;
Domain& Domain::operator=(Domain&&) noexcept = default;

void Domain::fit_ray_caster(std::span<const std::uint32_t> ids, const Objects& objects) {
  // Kept between calls, by id: objects migrate between ranks every frame,
  // so a rank's list seldom repeats in order. Building a k-d tree of 10^5
  // objects afresh took 0.67 s, casting 10^4 rays through it 0.4 s
  // (scaled-even, one process, the 2-core VM at a load of 9).
  if (!rays_) {
    auto c = std::make_unique<RayCaster>();
    Config config;
    config.world = world_;
    config.expected_objects = objects.count;
    c->structure = make_structure(options_.ray_algo, config);
    rays_ = std::move(c);
  }
  RayCaster& c = *rays_;
  const std::uint64_t call = ++c.calls;
  std::vector<Move> moves;
  for (std::size_t i = 0; i < objects.count; ++i) {
    const Shape s = objects.shape(i);
    const Filter f{objects.groups.empty() ? Filter{}.group : objects.groups[i], Filter{}.mask};
    auto [at, arrived] = c.by_id.try_emplace(ids[i]);
    RayCaster::Entry& e = at->second;
    if (arrived) {
      e.handle = c.structure->insert(s, ids[i], Motion::fixed, f);
      if (c.id_of_slot.size() <= e.handle.index) c.id_of_slot.resize(e.handle.index + 1);
      c.id_of_slot[e.handle.index] = ids[i];
    } else {
      if (e.call == call)
        throw std::invalid_argument("id " + std::to_string(ids[i]) + " is given twice");
      if (!(s == e.shape)) moves.push_back({e.handle, s});
      if (f.group != e.group) c.structure->set_filter(e.handle, f);
    }
    e.shape = s;
    e.group = f.group;
    e.call = call;
  }
  if (c.by_id.size() > objects.count)
    for (auto at = c.by_id.begin(); at != c.by_id.end();) {
      if (at->second.call == call) {
        ++at;
        continue;
      }
      c.structure->remove(at->second.handle);
      at = c.by_id.erase(at);
    }
  if (!moves.empty()) c.structure->update(moves);
  c.structure->settle();
}

const Domain::RayCaster& Domain::prepare_rays(const char* call, std::span<const std::uint32_t> ids,
                                              const Objects& objects, std::span<const Ray> rays,
                                              int root) {
  stats_ = Stats{};
  stats_.owned = objects.count;
  const auto t0 = std::chrono::steady_clock::now();
  // The same call on every rank: the batch (count and digest) and the root
  // are compared by one reduction of their minima and maxima, so ranks that
  // disagree all throw instead of waiting in different collectives.
  const std::uint64_t mine[3] = {rays.size(), batch_digest(rays),
                                 static_cast<std::uint64_t>(static_cast<std::int64_t>(root) + 1)};
  std::uint64_t low[3], high[3];
  MPI_Allreduce(mine, low, 3, MPI_UINT64_T, MPI_MIN, comm_);
  MPI_Allreduce(mine, high, 3, MPI_UINT64_T, MPI_MAX, comm_);
  const std::string where = std::string(call) + ": ";
  if (low[0] != high[0] || low[1] != high[1])
    throw MpiError(where +
                   "the ranks pass different batches of rays (every rank passes all of "
                   "them, the same on each)");
  if (low[2] != high[2]) throw MpiError(where + "the ranks pass different roots");
  if (root < kEveryRank || root >= size_)
    throw MpiError(where + "root " + std::to_string(root) + " is not a rank of the " +
                   std::to_string(size_) + " (nor kEveryRank)");
  if (rays.size() > static_cast<std::size_t>(INT_MAX))
    throw MpiError(where + "more than 2^31 - 1 rays in one call");
  // Every rank holds the same batch: each finds the same first bad ray.
  std::string error;
  for (std::size_t i = 0; i < rays.size() && error.empty(); ++i) {
    const std::string why = ray_problem(rays[i]);
    if (!why.empty()) error = where + "invalid ray " + std::to_string(i) + ": " + why;
  }
  agree(error);
  if (ids.size() != objects.count) {
    error = where + "rank " + std::to_string(rank_) + ": " + std::to_string(ids.size()) +
            " ids for " + std::to_string(objects.count) + " objects";
  } else {
    try {
      check_objects(objects);
      fit_ray_caster(ids, objects);
    } catch (const std::exception& e) {
      rays_.reset();  // perhaps half updated: the next call builds afresh
      error = where + "rank " + std::to_string(rank_) + ": " + e.what();
    }
  }
  stats_.exchange_seconds = since(t0);
  agree(error);
  return *rays_;
}

void Domain::closest_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                          std::span<const Ray> rays, std::span<IdHit> closest) {
  agree(closest.size() != rays.size() ? "closest_hits: rank " + std::to_string(rank_) + ": " +
                                            std::to_string(closest.size()) + " results for " +
                                            std::to_string(rays.size()) + " rays"
                                      : "");
  const RayCaster& caster = prepare_rays("closest_hits", ids, objects, rays, kEveryRank);
  auto t = std::chrono::steady_clock::now();
  const AnyBroadPhase& s = *caster.structure;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    IdHit best;
    // Clipping at each hit's t keeps the hits at exactly that t coming, so
    // that equal t are decided by id.
    s.cast_ray(rays[i], [&](Handle h, double hit_t) {
      const IdHit hit{hit_t, caster.id(h), true};
      if (before(hit, best)) best = hit;
      return hit_t;
    });
    closest[i] = best;
  }
  stats_.local_seconds = since(t);
  t = std::chrono::steady_clock::now();
  if (size_ > 1 && !rays.empty()) {
    const Bytes type(sizeof(IdHit));
    MPI_Op op;
    MPI_Op_create(&closest_op, 1, &op);
    MPI_Allreduce(MPI_IN_PLACE, closest.data(), static_cast<int>(rays.size()), type.type(), op,
                  comm_);
    MPI_Op_free(&op);
  }
  stats_.exchange_seconds += since(t);
}

void Domain::any_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                      std::span<const Ray> rays, std::span<std::uint8_t> hit) {
  agree(hit.size() != rays.size()
            ? "any_hits: rank " + std::to_string(rank_) + ": " + std::to_string(hit.size()) +
                  " results for " + std::to_string(rays.size()) + " rays"
            : "");
  const RayCaster& caster = prepare_rays("any_hits", ids, objects, rays, kEveryRank);
  auto t = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < rays.size(); ++i) hit[i] = caster.structure->any_hit(rays[i]) ? 1 : 0;
  stats_.local_seconds = since(t);
  t = std::chrono::steady_clock::now();
  if (size_ > 1 && !rays.empty())
    MPI_Allreduce(MPI_IN_PLACE, hit.data(), static_cast<int>(rays.size()), MPI_UINT8_T, MPI_MAX,
                  comm_);
  stats_.exchange_seconds += since(t);
}

void Domain::all_hits(std::span<const std::uint32_t> ids, const Objects& objects,
                      std::span<const Ray> rays, IdHitRows& out, int root) {
  const RayCaster& caster = prepare_rays("all_hits", ids, objects, rays, root);
  auto t = std::chrono::steady_clock::now();
  // This rank's hits in ray order; the rows are sorted where they arrive.
  std::vector<WireHit> mine;
  for (std::size_t i = 0; i < rays.size(); ++i)
    caster.structure->cast_ray(rays[i], [&](Handle h, double hit_t) {
      mine.push_back({hit_t, caster.id(h), static_cast<std::uint32_t>(i)});
      return kRayGoOn;
    });
  stats_.local_seconds = since(t);
  t = std::chrono::steady_clock::now();
  const bool everyone = root == kEveryRank;
  const bool receives = everyone || root == rank_;
  std::vector<long long> counts(static_cast<std::size_t>(size_));
  const long long count = static_cast<long long>(mine.size());
  MPI_Allgather(&count, 1, MPI_LONG_LONG, counts.data(), 1, MPI_LONG_LONG, comm_);
  long long total = 0;
  for (long long c : counts) total += c;
  // Every rank computed the same total: all refuse together.
  if (total > INT_MAX)
    throw MpiError("all_hits: " + std::to_string(total) + " hits to gather, more than 2^31 - 1");
  std::vector<int> recv_counts(counts.size()), displs(counts.size());
  int at = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    recv_counts[r] = static_cast<int>(counts[r]);
    displs[r] = at;
    at += recv_counts[r];
  }
  std::vector<WireHit> gathered(receives ? static_cast<std::size_t>(total) : 0);
  {
    const Bytes type(sizeof(WireHit));
    if (everyone)
      MPI_Allgatherv(mine.data(), static_cast<int>(count), type.type(), gathered.data(),
                     recv_counts.data(), displs.data(), type.type(), comm_);
    else
      MPI_Gatherv(mine.data(), static_cast<int>(count), type.type(), gathered.data(),
                  recv_counts.data(), displs.data(), type.type(), root, comm_);
  }
  out.offsets.clear();
  out.hits.clear();
  if (receives) {
    // Rows by a counting sort on the ray, then each row by (t, id).
    out.offsets.assign(rays.size() + 1, 0);
    for (const WireHit& w : gathered) ++out.offsets[w.ray + 1];
    for (std::size_t i = 0; i < rays.size(); ++i) out.offsets[i + 1] += out.offsets[i];
    out.hits.resize(gathered.size());
    std::vector<std::size_t> next(out.offsets.begin(), out.offsets.end() - 1);
    for (const WireHit& w : gathered) out.hits[next[w.ray]++] = IdHit{w.t, w.id, true};
    for (std::size_t i = 0; i < rays.size(); ++i)
      std::sort(out.hits.begin() + static_cast<std::ptrdiff_t>(out.offsets[i]),
                out.hits.begin() + static_cast<std::ptrdiff_t>(out.offsets[i + 1]), before);
  }
  stats_.exchange_seconds += since(t);
}

}  // namespace broadphase::mpi
