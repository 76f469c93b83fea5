// Pair finding over MPI ranks with broadphase::mpi (docs/distributed.md):
// each rank owns a block of a row of spheres, every overlapping pair of the
// whole row is reported once, on one rank, with the global ids.
//   mpirun -np 2 ./distributed      (prints: pairs 99, on 2 ranks)
#include <mpi.h>

#include <broadphase/distributed.hpp>
#include <cstdint>
#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  namespace bd = broadphase::distributed;
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  int status = 0;
  try {
    // 100 spheres of radius 1, 1.5 apart along x: neighbours overlap. Rank r
    // owns every size-th one, wherever it lies: ownership is free.
    std::vector<std::uint32_t> ids;
    std::vector<broadphase::Shape> shapes;
    for (std::uint32_t i = static_cast<std::uint32_t>(rank); i < 100;
         i += static_cast<std::uint32_t>(size)) {
      ids.push_back(i);
      shapes.push_back(broadphase::Shape::sphere({1.5 * i, 0, 0}, 1.0));
    }
    bd::Domain domain(MPI_COMM_WORLD, {{0, -10, -10}, {150, 10, 10}});
    std::vector<bd::IdPair> pairs;  // this rank's share
    domain.find_pairs(ids, shapes, pairs);
    unsigned long long mine = pairs.size(), all = 0;
    MPI_Reduce(&mine, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    if (rank == 0) std::printf("pairs %llu, on %d ranks\n", all, size);
  } catch (const bd::DistributedError& e) {  // thrown on every rank at once
    if (rank == 0) std::fprintf(stderr, "error: %s\n", e.what());
    status = 1;
  }
  MPI_Finalize();
  return status;
}
