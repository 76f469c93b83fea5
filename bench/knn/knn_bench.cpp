// knn of points queried by themselves: broadphase::KnnIndex against
// nanoflann's k-d tree (libnanoflann-dev), side by side in one run, one
// thread each, build included (docs/knn.md). Each (set, k) is measured
// `--repeats` times, the two alternating, and the medians are printed with
// their ratio; the k-th distances of both are compared on every row.
//
//   knn_bench [--n 1000000] [--repeats 3] [--k 1,8,32] [--sets uniform,clustered]
//             [--sigma 0.01] [--cell-points 2]
//
// Sets, in the unit cube: `uniform`; `clustered`: 1 000 Gaussian blobs
// (sigma 0.01, or --sigma) with centres uniform in the cube, every point in
// a blob.
#include <algorithm>
#include <broadphase/knn.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "knn_peer.hpp"

namespace {

std::vector<double> make(const std::string& set, std::size_t n, double sigma) {
  if (set != "uniform" && set != "clustered") {
    std::fprintf(stderr, "knn_bench: unknown set '%s' (uniform, clustered)\n", set.c_str());
    std::exit(2);
  }
  return broadphase::app::knn_points(set == "clustered", n, 2026, sigma);
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string part; std::getline(in, part, ',');) out.push_back(part);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t n = 1000000;
  double sigma = 0.01;
  broadphase::KnnConfig config;
  int repeats = 3;
  std::string ks = "1,8,32", sets = "uniform,clustered";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--n"))
      n = std::strtoull(argv[i + 1], nullptr, 10);
    else if (!std::strcmp(argv[i], "--repeats"))
      repeats = std::max(1, std::atoi(argv[i + 1]));
    else if (!std::strcmp(argv[i], "--k"))
      ks = argv[i + 1];
    else if (!std::strcmp(argv[i], "--cell-points"))
      config.cell_points = std::strtod(argv[i + 1], nullptr);
    else if (!std::strcmp(argv[i], "--sigma"))
      sigma = std::strtod(argv[i + 1], nullptr);
    else if (!std::strcmp(argv[i], "--sets"))
      sets = argv[i + 1];
    else {
      std::fprintf(stderr, "knn_bench: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  std::printf("# knn of %zu points queried by themselves, one thread, build included;\n", n);
  std::printf(
      "# medians of %d runs, alternating; nanoflann %x (leaf size 10); blobs' sigma %g;\n"
      "# %g points a cell\n",
      repeats, NANOFLANN_VERSION, sigma, config.cell_points);
  std::printf("%-10s %4s %12s %12s %8s %10s\n", "set", "k", "ours_s", "nanoflann_s", "ratio",
              "kth_equal");
  for (const std::string& set : split(sets)) {
    const std::vector<double> xyz = make(set, n, sigma);
    const broadphase::Points pts = broadphase::Points::rows(xyz.data(), n);
    for (const std::string& kt : split(ks)) {
      const std::size_t k = std::strtoull(kt.c_str(), nullptr, 10);
      std::vector<double> ours, theirs;
      std::vector<double> d2(n * k);
      std::vector<std::int64_t> index(n * k);
      std::vector<double> nd2(n * k);
      std::vector<std::uint32_t> nindex(n * k);
      for (int r = 0; r < repeats; ++r) {
        auto t0 = std::chrono::steady_clock::now();
        {
          const broadphase::KnnIndex grid(pts, config);
          grid.knn_self(k, false, d2, index, 1);
        }
        ours.push_back(seconds_since(t0));
        t0 = std::chrono::steady_clock::now();
        {
          const broadphase::app::NanoflannCloud cloud{&xyz};
          broadphase::app::NanoflannTree tree(3, cloud,
                                              nanoflann::KDTreeSingleIndexAdaptorParams(10));
          tree.buildIndex();
          for (std::size_t i = 0; i < n; ++i)
            tree.knnSearch(&xyz[3 * i], k, &nindex[i * k], &nd2[i * k]);
        }
        theirs.push_back(seconds_since(t0));
      }
      std::size_t equal = 0;
      for (std::size_t i = 0; i < n; ++i) equal += d2[i * k + k - 1] == nd2[i * k + k - 1];
      const double a = median(ours), b = median(theirs);
      std::printf("%-10s %4zu %12.3f %12.3f %8.2f %9.4f%%\n", set.c_str(), k, a, b, b / a,
                  100.0 * static_cast<double>(equal) / static_cast<double>(n));
      std::fflush(stdout);
    }
  }
}
