// Weighted bisection over 2 ranks (run under mpiexec -np 2): objects spread
// evenly along x over [0, 100], weighing 3 below x = 50 and 1 above, must be
// cut at x = 100/3 (half the weight on each side), at x = 50 by counts, and
// bad weights must be refused on every rank; bad options are refused as
// InvalidConfig on every rank. Exits non-zero on a failure.
#include <mpi.h>

#include <broadphase/config_error.hpp>
#include <broadphase/mpi.hpp>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace dist = broadphase::mpi;
using broadphase::Shape;

namespace {

int failures = 0;

void expect(bool ok, const std::string& what, int rank) {
  if (ok) return;
  ++failures;
  std::fprintf(stderr, "rank %d: FAILED: %s\n", rank, what.c_str());
}

double first_cut(const dist::Domain& d) { return d.partition().region(0).hi[0]; }

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  {
    dist::Options o;
    o.decomposition = dist::Decomposition::bisection;
    dist::Domain d(MPI_COMM_WORLD, {{0, 0, 0}, {100, 100, 100}}, o);
    // Every rank makes all objects and keeps those its subdomain holds, as
    // after a migration.
    constexpr int kObjects = 1200;
    auto owned = [&](std::vector<Shape>& shapes, std::vector<double>& weights) {
      shapes.clear();
      weights.clear();
      for (int id = 0; id < kObjects; ++id) {
        const double x = (id + 0.5) * 100.0 / kObjects;
        if (d.partition().owner({x, 50, 50}) != rank) continue;
        shapes.push_back(Shape::sphere({x, 50, 50}, 0.01));
        weights.push_back(x < 50 ? 3.0 : 1.0);
      }
    };
    std::vector<Shape> shapes;
    std::vector<double> weights;
    owned(shapes, weights);
    if (size == 2) {
      d.balance(shapes);
      expect(std::fabs(first_cut(d) - 50) < 0.5,
             "counts: cut at " + std::to_string(first_cut(d)) + ", 50 wanted", rank);
      owned(shapes, weights);
      expect(d.rebalance(shapes, weights), "weights: a rebalance was due (1.5 x the mean)", rank);
      expect(std::fabs(first_cut(d) - 100.0 / 3) < 0.5,
             "weights: cut at " + std::to_string(first_cut(d)) + ", 33.3 wanted", rank);
      owned(shapes, weights);
      expect(!d.rebalance(shapes, weights), "weights: balanced, no rebalance due", rank);
    }
    // Bad weights are refused on every rank, naming the rank that gave them.
    std::vector<double> bad = weights;
    if (rank == size - 1) bad.assign(shapes.size(), -1.0);
    try {
      d.balance(shapes, bad);
      expect(false, "a negative weight was accepted", rank);
    } catch (const dist::MpiError& e) {
      const std::string m = e.what();
      expect(m.find("rank " + std::to_string(size - 1)) != std::string::npos &&
                 m.find("weight") != std::string::npos,
             "message names the rank and the weight: " + m, rank);
    }
    try {
      d.balance(shapes, std::span<const double>(weights.data(), rank == 0 ? 1 : weights.size()));
      expect(false, "weights of the wrong count were accepted", rank);
    } catch (const dist::MpiError& e) {
      expect(std::string(e.what()).find("weights for") != std::string::npos,
             std::string("message names the count: ") + e.what(), rank);
    }
  }
  {
    // Bad options are an InvalidConfig, on every rank, with their message.
    auto refused = [&](const std::string& what, const std::string& message, auto make) {
      try {
        make();
        expect(false, what + ": accepted", rank);
      } catch (const broadphase::InvalidConfig& e) {
        expect(std::string(e.what()).find(message) != std::string::npos,
               what + ": message " + e.what(), rank);
      } catch (const std::exception& e) {
        expect(false, what + ": not an InvalidConfig: " + e.what(), rank);
      }
    };
    const broadphase::Aabb world{{0, 0, 0}, {100, 100, 100}};
    dist::Options o;
    o.margin = std::nan("");
    refused("a NaN margin", "the margin must be finite and >= 0",
            [&] { dist::Domain bad(MPI_COMM_WORLD, world, o); });
    o = {};
    o.dims = {size + 1, 1, 1};
    refused("a grid that does not fit", "does not fit",
            [&] { dist::Domain bad(MPI_COMM_WORLD, world, o); });
    o = {};
    o.max_ghost_ranks = 0;
    refused("no ghost rank", "max_ghost_ranks must be >= 1",
            [&] { dist::Domain bad(MPI_COMM_WORLD, world, o); });
    dist::Domain d(MPI_COMM_WORLD, world);
    refused("a negative skin", "the skin must be finite and >= 0",
            [&] { dist::PairTracker bad(d, -1); });
  }
  int all = 0;
  MPI_Allreduce(&failures, &all, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
  if (rank == 0) std::printf("%s (%d failures over %d ranks)\n", all ? "FAILED" : "ok", all, size);
  MPI_Finalize();
  return all == 0 ? 0 : 1;
}
