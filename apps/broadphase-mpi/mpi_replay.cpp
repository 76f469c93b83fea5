#include "mpi_replay.hpp"

#include <broadphase/scenes/generate.hpp>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <limits>
#include <stdexcept>
#include <string>

namespace broadphase::mpi_app {

using mpi::agree;
using mpi::MpiError;

namespace {

double since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

int rank_of(MPI_Comm comm) {
  int r = 0;
  MPI_Comm_rank(comm, &r);
  return r;
}
int size_of(MPI_Comm comm) {
  int s = 1;
  MPI_Comm_size(comm, &s);
  return s;
}

std::uint64_t block_begin(std::uint64_t n, int rank, int size) {
  // n < 2^32 and rank < 2^31: the product fits.
  return n * static_cast<std::uint64_t>(rank) / static_cast<std::uint64_t>(size);
}

}  // namespace

Share scatter_share(MPI_Comm comm, const Scene& scene) {
  const int rank = rank_of(comm), size = size_of(comm);
  Share s;
  double head[4] = {scene.world, static_cast<double>(scene.size()), scene.has_filters() ? 1.0 : 0.0,
                    static_cast<double>(scene.rays.size())};
  MPI_Bcast(head, 4, MPI_DOUBLE, 0, comm);
  s.world = head[0];
  s.n = static_cast<std::uint64_t>(head[1]);
  s.filtered = head[2] != 0;
  // Rays are global: every rank casts all of them against its own objects.
  agree(comm, head[3] * sizeof(Ray) > 2e9 ? "the scene's rays exceed 2 GB" : "");
  s.rays.resize(static_cast<std::size_t>(head[3]));
  if (rank == 0) s.rays = scene.rays;
  MPI_Bcast(s.rays.data(), static_cast<int>(s.rays.size() * sizeof(Ray)), MPI_BYTE, 0, comm);
  std::string error;
  if (s.n > std::numeric_limits<std::uint32_t>::max())
    error = "the scene has more objects than 32-bit ids can name";
  if (static_cast<double>(s.n) * sizeof(Body) / size > 2e9)
    error = "a share of the scene exceeds 2 GB: generate it on the ranks (--gen) instead";
  agree(comm, error);
  std::vector<int> counts(static_cast<std::size_t>(size)), displs(counts.size());
  for (int r = 0; r < size; ++r) {
    const std::uint64_t b = block_begin(s.n, r, size), e = block_begin(s.n, r + 1, size);
    counts[static_cast<std::size_t>(r)] = static_cast<int>((e - b) * sizeof(Body));
    displs[static_cast<std::size_t>(r)] = static_cast<int>(b * sizeof(Body));
  }
  std::vector<Body> all;
  if (rank == 0) {
    all.resize(s.n);
    for (std::size_t i = 0; i < s.n; ++i)
      all[i] = {scene.objects[i], scene.velocity[i], static_cast<std::uint32_t>(i),
                scene.filter(i)};
  }
  // Byte displacements are ints: the whole scene must stay below 2 GB here.
  agree(comm, rank == 0 && static_cast<double>(s.n) * sizeof(Body) > 2e9
                  ? "a scene file above 2 GB of objects cannot be scattered: use --gen"
                  : "");
  s.bodies.resize(static_cast<std::size_t>(counts[static_cast<std::size_t>(rank)]) / sizeof(Body));
  MPI_Scatterv(all.data(), counts.data(), displs.data(), MPI_BYTE, s.bodies.data(),
               counts[static_cast<std::size_t>(rank)], MPI_BYTE, 0, comm);
  return s;
}

Share read_share(MPI_Comm comm, const std::string& path) {
  Scene scene;
  std::string error;
  if (rank_of(comm) == 0) {
    try {
      scene = read_scene(path);
      if (scene.is_periodic())
        error = path +
                ": a periodic world, which broadphase-mpi does not take yet (`broadphase "
                "run` replays it on one process)";
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  agree(comm, error);
  return scatter_share(comm, scene);
}

Share generate_share(MPI_Comm comm, Distribution d, std::uint64_t n, std::uint64_t seed) {
  const int rank = rank_of(comm), size = size_of(comm);
  Share s;
  s.n = n;
  s.world = counter_world(d, n);
  std::string error;
  std::vector<Shape> shapes;
  std::vector<Vec3> velocity;
  const std::uint64_t b = block_begin(n, rank, size), e = block_begin(n, rank + 1, size);
  try {
    if (n > std::numeric_limits<std::uint32_t>::max())
      throw std::invalid_argument("more objects than 32-bit ids can name");
    generate_counter_range(d, n, seed, b, e, shapes, velocity);
  } catch (const std::exception& ex) {
    error = ex.what();
  }
  agree(comm, error);
  s.bodies.reserve(shapes.size());
  for (std::size_t i = 0; i < shapes.size(); ++i)
    s.bodies.push_back({shapes[i], velocity[i], static_cast<std::uint32_t>(b + i), Filter{}});
  return s;
}

MpiReplay::MpiReplay(MPI_Comm comm, Share share, const mpi::Options& options, double skin)
    : n_(share.n),
      world_(share.world),
      domain_(comm, Aabb{{0, 0, 0}, {share.world, share.world, share.world}}, options),
      skin_(skin),
      bodies_(std::move(share.bodies)),
      filtered_(share.filtered),
      rays_(std::move(share.rays)) {
  if (skin > 0) {
    agree(comm, options.algo != mpi::kLeanPath
                    ? "a skin works with the lean path (--algo arrays) only"
                    : "");
    tracker_ = std::make_unique<mpi::PairTracker>(domain_, skin);
  }
  // A test hook: BROADPHASE_MPI_FAIL=RANK:FRAME[:abort] makes that rank
  // throw at that frame, inside an agreed phase or (abort) outside one.
  if (const char* f = std::getenv("BROADPHASE_MPI_FAIL")) {
    const std::string s = f;
    const auto c1 = s.find(':');
    if (c1 != std::string::npos) {
      fail_rank_ = std::atoi(s.substr(0, c1).c_str());
      fail_frame_ = std::atoi(s.substr(c1 + 1).c_str());
      fail_abort_ = s.find(":abort") != std::string::npos;
    }
  }
  {
    std::vector<Shape> shapes;
    shapes.reserve(bodies_.size());
    for (const Body& b : bodies_) shapes.push_back(b.shape);
    domain_.balance(shapes);
  }
  FrameReport unused;
  migrate(unused);
  // Room for arrivals: a rank that receives more than it sends would
  // otherwise grow its bodies by a copy of all of them (98 MB at 1 024 000
  // objects of 96 bytes) in the middle of a frame, which showed as 25-30 ms of
  // "migration" in the mean over 10-20 frames of the weak-scaling runs.
  bodies_.reserve(bodies_.size() + bodies_.size() / 16 + 1024);
}

Objects MpiReplay::view() const {
  return mpi::shapes_view(bodies_.empty() ? nullptr : &bodies_[0].shape, bodies_.size(),
                          static_cast<std::ptrdiff_t>(sizeof(Body)));
}

void MpiReplay::migrate(FrameReport& r) {
  const mpi::Stats before = domain_.stats();
  domain_.migrate(bodies_, [](const Body& b) { return b.shape.center; });
  r.stats.bytes_sent += domain_.stats().bytes_sent - before.bytes_sent;
  r.stats.messages_sent += domain_.stats().messages_sent - before.messages_sent;
}

FrameReport MpiReplay::next() {
  FrameReport r;
  const int rank = domain_.rank();
  MPI_Comm comm = domain_.comm();
  // Motion on the owning rank, as the contract writes it.
  auto t = std::chrono::steady_clock::now();
  if (fail_abort_ && rank == fail_rank_ && frame_ == fail_frame_)
    throw std::runtime_error("rank " + std::to_string(rank) + ": injected failure at frame " +
                             std::to_string(frame_) + " (outside an agreed phase)");
  std::string error;
  std::uint64_t overflow = std::numeric_limits<std::uint64_t>::max();
  try {
    if (rank == fail_rank_ && frame_ == fail_frame_)
      throw std::runtime_error("rank " + std::to_string(rank) + ": injected failure at frame " +
                               std::to_string(frame_));
    if (frame_ > 0)
      for (Body& b : bodies_) {
        Vec3& v = b.velocity;
        if (v.x == 0 && v.y == 0 && v.z == 0) continue;
        for (int a = 0; a < 3; ++a) step_axis(b.shape.center[a], v[a], world_);
        if (!is_valid(b.shape)) overflow = std::min<std::uint64_t>(overflow, b.id);
      }
  } catch (const std::exception& e) {
    error = e.what();
  }
  agree(comm, error);
  std::uint64_t first = overflow;
  MPI_Allreduce(&overflow, &first, 1, MPI_UINT64_T, MPI_MIN, comm);
  if (first != std::numeric_limits<std::uint64_t>::max())
    throw MpiError("frame " + std::to_string(frame_) + ": object " + std::to_string(first) +
                   " moves beyond the range of doubles (its motion overflows)");
  r.phases.step = since(t);

  // Migration to the owner of the new centre: an all-to-all, so an object
  // that jumped past its neighbour still arrives. With a skin, objects stay
  // where they are until the tracker must rebuild its ghost lists anyway.
  t = std::chrono::steady_clock::now();
  r.rebuilt = tracker_ == nullptr || tracker_->rebuild_due(view());
  if (frame_ > 0 && r.rebuilt) migrate(r);
  r.phases.migration = since(t);

  t = std::chrono::steady_clock::now();
  if (r.rebuilt && domain_.rebalance(view())) {
    r.rebalanced = true;
    migrate(r);
  }
  r.phases.balancing = since(t);

  // Every object owned by exactly one rank, inside that rank's subdomain
  // (with a skin, between rebuilds: within the skin of it).
  t = std::chrono::steady_clock::now();
  ids_.clear();
  groups_.clear();
  masks_.clear();
  std::uint64_t local[3] = {bodies_.size(), 0, 0}, x = 0;
  const double slack = r.rebuilt ? 0 : skin_;
  const Aabb& region = domain_.partition().region(rank);
  for (const Body& b : bodies_) {
    ids_.push_back(b.id);
    if (filtered_) {
      groups_.push_back(b.filter.group);
      masks_.push_back(b.filter.mask);
    }
    local[1] += b.id;
    x ^= b.id;
    if (slack == 0) {
      if (!domain_.partition().holds(rank, b.shape.center)) ++local[2];
    } else {
      for (int a = 0; a < 3; ++a)
        if (!(region.lo[a] - slack <= b.shape.center[a] &&
              b.shape.center[a] < region.hi[a] + slack)) {
          ++local[2];
          break;
        }
    }
  }
  std::uint64_t global[3], gx = 0, most = 0;
  MPI_Allreduce(local, global, 3, MPI_UINT64_T, MPI_SUM, comm);
  MPI_Allreduce(&x, &gx, 1, MPI_UINT64_T, MPI_BXOR, comm);
  MPI_Allreduce(&local[0], &most, 1, MPI_UINT64_T, MPI_MAX, comm);
  std::uint64_t want_sum = n_ == 0 ? 0 : (n_ % 2 == 0 ? (n_ / 2) * (n_ - 1) : n_ * ((n_ - 1) / 2));
  std::uint64_t want_xor = 0;
  switch ((n_ - 1) % 4) {  // xor of 0..n-1
    case 0:
      want_xor = n_ - 1;
      break;
    case 1:
      want_xor = 1;
      break;
    case 2:
      want_xor = n_;
      break;
    default:
      want_xor = 0;
      break;
  }
  if (n_ == 0) want_xor = 0;
  if (global[0] != n_ || global[1] != want_sum || gx != want_xor || global[2] != 0)
    throw MpiError("frame " + std::to_string(frame_) + ": ownership check failed (" +
                   std::to_string(global[0]) + " owned of " + std::to_string(n_) + ", " +
                   std::to_string(global[2]) + " outside their owner's subdomain)");
  r.owned = local[0];
  r.max_owned = most;
  r.phases.reduction = since(t);

  pairs_.clear();
  Objects objects = view();
  objects.groups = groups_;
  objects.masks = masks_;
  if (tracker_)
    tracker_->find_pairs(ids_, objects, pairs_);
  else
    domain_.find_pairs(ids_, objects, pairs_);
  const mpi::Stats& s = tracker_ ? tracker_->stats() : domain_.stats();
  r.stats.owned = s.owned;
  r.stats.ghosts = s.ghosts;
  r.stats.shared = s.shared;
  r.stats.local_pairs = s.local_pairs;
  r.stats.bytes_sent += s.bytes_sent;
  r.stats.messages_sent += s.messages_sent;
  r.phases.exchange = s.exchange_seconds;
  r.phases.local = s.local_seconds;

  t = std::chrono::steady_clock::now();
  FrameDigest mine;
  for (const mpi::IdPair& p : pairs_) mine.add(p.a, p.b);
  std::uint64_t d[2] = {mine.pairs, mine.hash}, sum[2];
  MPI_Allreduce(d, sum, 2, MPI_UINT64_T, MPI_SUM, comm);
  r.digest.pairs = sum[0];
  r.digest.hash = sum[1];
  r.phases.reduction += since(t);

  // Every hit to rank 0, which digests the rows as `broadphase run` does
  // (each row's first hit is the ray's closest) and tells the others.
  if (!rays_.empty()) {
    t = std::chrono::steady_clock::now();
    const std::clock_t cpu = std::clock();
    domain_.all_hits(ids_, objects, rays_, rows_, 0);
    std::uint64_t h[3] = {0, 0, 0};
    if (rank == 0) {
      HitDigest d;
      for (std::size_t k = 0; k < rays_.size(); ++k) {
        RayHits hits(static_cast<std::uint32_t>(k));
        for (std::size_t i = rows_.offsets[k]; i < rows_.offsets[k + 1]; ++i)
          hits.add(rows_.hits[i].id, rows_.hits[i].t);
        hits.add_to(d);
      }
      h[0] = d.hits;
      h[1] = d.hash;
      h[2] = d.closest;
    }
    MPI_Bcast(h, 3, MPI_UINT64_T, 0, comm);
    r.hits = {h[0], h[1], h[2]};
    r.phases.rays = since(t);
    r.phases.rays_cpu = static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC;
  }
  ++frame_;
  return r;
}

void MpiReplay::check_ray_entry_points() {
  Objects objects = view();
  objects.groups = groups_;
  objects.masks = masks_;
  std::vector<mpi::IdHit> closest(rays_.size());
  std::vector<std::uint8_t> any(rays_.size());
  domain_.closest_hits(ids_, objects, rays_, closest);
  domain_.any_hits(ids_, objects, rays_, any);
  std::string bad;
  if (domain_.rank() == 0)
    for (std::size_t k = 0; k < rays_.size() && bad.empty(); ++k) {
      const bool some = rows_.offsets[k + 1] > rows_.offsets[k];
      const mpi::IdHit want = some ? rows_.hits[rows_.offsets[k]] : mpi::IdHit{};
      if (!(closest[k] == want) || any[k] != (some ? 1 : 0))
        bad = "ray " + std::to_string(k) + ": closest_hits gives " +
              (closest[k].hit ? "id " + std::to_string(closest[k].id) : std::string("no hit")) +
              " and any_hits " + std::to_string(any[k]) + ", all_hits' row " +
              (some ? "starts with id " + std::to_string(want.id) : std::string("is empty"));
    }
  agree(domain_.comm(), bad);
}

FrameDigest MpiReplay::digest_through_arrays() {
  // Struct-of-arrays copies with mixed kinds, as a particle code keeps them.
  const std::size_t n = bodies_.size();
  std::vector<double> x(n), y(n), z(n), r(n), hx(n), hy(n), hz(n);
  std::vector<std::uint8_t> kind(n);
  std::vector<std::uint32_t> ids(n), groups, masks;
  for (std::size_t i = 0; i < n; ++i) {
    const Shape& s = bodies_[i].shape;
    x[i] = s.center.x;
    y[i] = s.center.y;
    z[i] = s.center.z;
    r[i] = s.half.x;
    hx[i] = s.half.x;
    hy[i] = s.half.y;
    hz[i] = s.half.z;
    kind[i] = s.is_sphere() ? 0 : 1;
    ids[i] = bodies_[i].id;
    if (filtered_) {
      groups.push_back(bodies_[i].filter.group);
      masks.push_back(bodies_[i].filter.mask);
    }
  }
  Objects o;
  o.count = n;
  o.x = Column::of(x.data());
  o.y = Column::of(y.data());
  o.z = Column::of(z.data());
  o.radius = Column::of(r.data());
  o.half_x = Column::of(hx.data());
  o.half_y = Column::of(hy.data());
  o.half_z = Column::of(hz.data());
  o.kind = kind.data();
  o.groups = groups;
  o.masks = masks;
  std::vector<mpi::IdPair> pairs;
  domain_.find_pairs(ids, o, pairs);
  FrameDigest mine;
  for (const mpi::IdPair& p : pairs) mine.add(p.a, p.b);
  std::uint64_t d[2] = {mine.pairs, mine.hash}, sum[2];
  MPI_Allreduce(d, sum, 2, MPI_UINT64_T, MPI_SUM, domain_.comm());
  return {sum[0], sum[1]};
}

}  // namespace broadphase::mpi_app
