// The point sets knn is measured on and nanoflann's k-d tree over them
// (libnanoflann-dev; with BROADPHASE_HAVE_NANOFLANN defined): shared by the
// lab's neighbours section (lab/experiments/neighbours.cpp) and
// bench/knn/knn_bench.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#if defined(BROADPHASE_HAVE_NANOFLANN)
#include <nanoflann.hpp>
#endif

namespace broadphase::app {

/// `n` points in the unit cube, rows of x, y, z: uniform, or in 1 000
/// Gaussian blobs of standard deviation `sigma` whose centres are uniform.
inline std::vector<double> knn_points(bool clustered, std::size_t n, std::uint64_t seed,
                                      double sigma = 0.01) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> xyz(3 * n);
  if (!clustered) {
    for (double& v : xyz) v = u(rng);
    return xyz;
  }
  std::vector<double> centres(3 * 1000);
  for (double& v : centres) v = u(rng);
  std::normal_distribution<double> g(0, sigma);
  std::uniform_int_distribution<std::size_t> blob(0, 999);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t b = blob(rng);
    for (std::size_t a = 0; a < 3; ++a) xyz[3 * i + a] = centres[3 * b + a] + g(rng);
  }
  return xyz;
}

#if defined(BROADPHASE_HAVE_NANOFLANN)
/// nanoflann's view of the rows of `xyz`.
struct NanoflannCloud {
  const std::vector<double>* xyz;
  std::size_t kdtree_get_point_count() const { return xyz->size() / 3; }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return (*xyz)[3 * i + d]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using NanoflannTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, NanoflannCloud>,
                                        NanoflannCloud, 3, std::uint32_t>;
#endif

}  // namespace broadphase::app
