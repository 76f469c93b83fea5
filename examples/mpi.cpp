// Pair finding over MPI ranks with broadphase::mpi (docs/mpi.md):
// each rank owns a block of a row of spheres, every overlapping pair of the
// whole row is reported once, on one rank, with the global ids.
// Then ten frames of motion through a PairTracker with a skin.
//   mpirun -np 2 ./mpi_example      (prints: pairs 99, on 2 ranks, then
//                                    10 frames, 99 to 99 pairs, ghost lists built 3 times)
#include <mpi.h>

#include <broadphase/mpi.hpp>
#include <cstdint>
#include <cstdio>
#include <vector>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  namespace bd = broadphase::mpi;
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

    // Frames: every sphere drifts along y by 1/8 a frame. The tracker keeps
    // its ghost lists while each sphere stays within the skin (0.5) of where
    // it was at the last rebuild, reading the shapes in place.
    bd::PairTracker tracker(domain, 0.5);
    unsigned long long fewest = ~0ull, most = 0;
    for (int frame = 0; frame < 10; ++frame) {
      for (broadphase::Shape& s : shapes) s.center.y += 0.125;
      pairs.clear();
      tracker.find_pairs(
          ids, bd::shapes_view(shapes.data(), shapes.size(), sizeof(broadphase::Shape)), pairs);
      mine = pairs.size();
      MPI_Reduce(&mine, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
      fewest = all < fewest ? all : fewest;
      most = all > most ? all : most;
    }
    if (rank == 0)
      std::printf("10 frames, %llu to %llu pairs, ghost lists built %llu times\n", fewest, most,
                  static_cast<unsigned long long>(tracker.rebuilds()));
  } catch (const bd::MpiError& e) {  // thrown on every rank at once
    if (rank == 0) std::fprintf(stderr, "error: %s\n", e.what());
    status = 1;
  }
  MPI_Finalize();
  return status;
}
