// broadphase-mpi: the replay contract over MPI ranks.
//
//   mpirun -np P broadphase-mpi run --scene F --algo NAME --frames K [--grid AxBxC | --bisect]
//   mpirun -np P broadphase-mpi run --gen KIND --n N --seed S ...
//   mpirun -np P broadphase-mpi check --scene F... [--nasty]   (tests: one process vs P ranks)
//   broadphase-mpi gen --gen KIND --n N --seed S --out F        (a counter-generated scene file)
//
// Rank 0 prints what `broadphase run` prints, with version 3 scenes'
// collision filters and rays (each rank casts every ray against its own
// objects; the hits are gathered on rank 0).
// Errors: a failure agreed by every rank (a bad scene, a bad option, an
// invalid object, a rank that threw inside a collective step) prints the
// message on rank 0 and every rank exits with status 1; anything else prints on the rank that
// failed and aborts the whole job (MPI_Abort), so no run can hang.
#include <mpi.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <broadphase/detail/median.hpp>
#include <broadphase/mpi.hpp>
#include <broadphase/registry.hpp>
#include <broadphase/scenes/generate.hpp>
#include <broadphase/scenes/replay.hpp>
#include <broadphase/scenes/scene.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mpi_replay.hpp"

namespace {

using broadphase::Distribution;
using broadphase::FrameDigest;
using broadphase::hex16;
using broadphase::HitDigest;
using broadphase::mpi::MpiError;
namespace dist = broadphase::mpi;
namespace mpi_app = broadphase::mpi_app;

int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}
int world_size() {
  int s = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &s);
  return s;
}

struct Common {
  std::string scene;
  std::string gen;
  std::uint64_t n = 0;
  std::uint64_t per_rank = 0;
  std::uint64_t seed = 1;
  std::string algo = broadphase::mpi::kLeanPath;
  int frames = 100;
  std::string grid;
  bool bisect = false;
  double margin = 0;
  double threshold = 1.1;
  std::string balance_by = "objects";
  int max_ghost_ranks = 4;
  double skin = 0;
  bool json = false;
  bool skip_local = false;
};

void add_common(CLI::App* cmd, Common& o) {
  cmd->add_option(
         "--algo", o.algo,
         "Local pairs: a structure by name (name:key=value,...), or 'arrays' for the lean path")
      ->default_val(broadphase::mpi::kLeanPath);
  cmd->add_option("--frames", o.frames, "Number of frames")
      ->default_val(100)
      ->check(CLI::Range(1, 100000000));
  cmd->add_option("--grid", o.grid, "Cartesian process grid AxBxC (default: MPI_Dims_create)");
  cmd->add_flag("--bisect", o.bisect, "Weighted recursive coordinate bisection instead of a grid");
  cmd->add_option("--margin", o.margin, "Ghost margin (world units); also the thinnest subdomain")
      ->default_val(0)
      ->check(CLI::Range(0.0, 1e300));
  cmd->add_option("--threshold", o.threshold,
                  "Bisection: rebalance when the most loaded rank exceeds the mean times this")
      ->default_val(1.1)
      ->check(CLI::Range(1.0, 1e300));
  cmd->add_option("--balance-by", o.balance_by,
                  "Bisection: what the cuts balance, 'objects' (counts, deterministic) or "
                  "'measured' (each rank's last local-pairs time over its objects)")
      ->default_val("objects")
      ->check(CLI::IsMember({"objects", "measured"}));
  cmd->add_option("--max-ghost-ranks", o.max_ghost_ranks,
                  "Objects reaching more ranks go to the list every rank holds")
      ->default_val(4)
      ->check(CLI::Range(1, 1 << 30));
  cmd->add_option("--skin", o.skin,
                  "Keep ghost lists and local pairs between frames while objects stay within "
                  "this distance (world units) of where they were; objects then migrate only "
                  "when the lists are rebuilt. 0: everything afresh every frame")
      ->default_val(0)
      ->check(CLI::Range(0.0, 1e300));
}

dist::Options domain_options(const Common& o) {
  dist::Options d;
  d.algo = o.algo;
  d.margin = o.margin;
  d.rebalance_threshold = o.threshold;
  d.balance_by = o.balance_by == "measured" ? dist::BalanceBy::measured : dist::BalanceBy::objects;
  d.max_ghost_ranks = o.max_ghost_ranks;
  d.local_pairs = !o.skip_local;
  if (o.bisect) {
    if (!o.grid.empty()) throw broadphase::InvalidConfig("--grid and --bisect exclude each other");
    d.decomposition = dist::Decomposition::bisection;
  } else if (!o.grid.empty()) {
    try {
      d.dims = dist::parse_dims(o.grid);
    } catch (const broadphase::InvalidConfig& e) {
      throw broadphase::InvalidConfig(std::string("--grid: ") + e.what());
    }
  }
  // The structure name is checked here, on every rank alike, before any data moves.
  if (d.algo != dist::kLeanPath) broadphase::make_structure(d.algo);
  return d;
}

Distribution parse_kind(const std::string& kind) {
  try {
    const Distribution d = broadphase::parse_distribution(kind);
    if (!broadphase::counter_supported(d))
      throw std::invalid_argument("'" + kind + "' is not available in counter generation");
    return d;
  } catch (const std::invalid_argument& e) {
    throw MpiError(std::string("--gen: ") + e.what());
  }
}

mpi_app::Share load(const Common& o) {
  if (o.scene.empty() == o.gen.empty())
    throw MpiError("give either --scene FILE or --gen KIND (with --n or --per-rank)");
  if (!o.scene.empty()) return mpi_app::read_share(MPI_COMM_WORLD, o.scene);
  const Distribution d = parse_kind(o.gen);
  const std::uint64_t n =
      o.per_rank > 0 ? o.per_rank * static_cast<std::uint64_t>(world_size()) : o.n;
  return mpi_app::generate_share(MPI_COMM_WORLD, d, n, o.seed);
}

using broadphase::detail::median;

// Per-rank sums over the frames, gathered to rank 0 for --json.
struct RankTotals {
  double step = 0, migration = 0, balancing = 0, exchange = 0, local = 0, reduction = 0, rays = 0,
         rays_cpu = 0;
  double ghosts = 0, owned = 0, shared = 0, bytes = 0, messages = 0, pairs = 0;
};

void run(const Common& o) {
  const dist::Options options = domain_options(o);
  const auto t_load = std::chrono::steady_clock::now();
  mpi_app::Share share = load(o);
  const double world = share.world;
  const auto t_setup = std::chrono::steady_clock::now();
  mpi_app::MpiReplay replay(MPI_COMM_WORLD, std::move(share), options, o.skin);
  const double setup_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_setup).count();
  const double load_s = std::chrono::duration<double>(t_setup - t_load).count();
  const bool root = world_rank() == 0;
  std::string out;
  FrameDigest total;
  HitDigest hits;
  RankTotals mine;
  std::vector<double> frame_ms;
  double worst_imbalance = 0, last_imbalance = 0;
  int rebalances = 0, rebuilds = 0;
  for (int f = 0; f < o.frames; ++f) {
    mpi_app::FrameReport r;
    const auto t0 = std::chrono::steady_clock::now();
    try {
      r = replay.next();
    } catch (...) {
      // The frames done so far are printed before the error.
      if (root && !o.json) std::fwrite(out.data(), 1, out.size(), stdout);
      std::fflush(stdout);
      throw;
    }
    frame_ms.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() * 1e3);
    total.pairs += r.digest.pairs;
    total.hash += r.digest.hash;
    hits.hits += r.hits.hits;
    hits.hash += r.hits.hash;
    hits.closest += r.hits.closest;
    mine.step += r.phases.step;
    mine.migration += r.phases.migration;
    mine.balancing += r.phases.balancing;
    mine.exchange += r.phases.exchange;
    mine.local += r.phases.local;
    mine.reduction += r.phases.reduction;
    mine.rays += r.phases.rays;
    mine.rays_cpu += r.phases.rays_cpu;
    mine.ghosts += static_cast<double>(r.stats.ghosts);
    mine.owned += static_cast<double>(r.owned);
    mine.shared += static_cast<double>(r.stats.shared);
    mine.bytes += static_cast<double>(r.stats.bytes_sent);
    mine.messages += static_cast<double>(r.stats.messages_sent);
    mine.pairs += static_cast<double>(r.stats.local_pairs);
    rebalances += r.rebalanced ? 1 : 0;
    rebuilds += r.rebuilt ? 1 : 0;
    const double mean = static_cast<double>(replay.size()) / world_size();
    last_imbalance = mean > 0 ? static_cast<double>(r.max_owned) / mean : 1.0;
    worst_imbalance = std::max(worst_imbalance, last_imbalance);
    if (root && !o.json) {
      out += broadphase::frame_line(f, r.digest, replay.has_rays() ? &r.hits : nullptr) + '\n';
      if (out.size() > (1u << 16)) {
        std::fwrite(out.data(), 1, out.size(), stdout);
        out.clear();
      }
    }
  }
  if (!o.json) {
    if (root) std::fwrite(out.data(), 1, out.size(), stdout);
    return;
  }
  const int p = world_size();
  constexpr int kFields = sizeof(RankTotals) / sizeof(double);
  std::vector<RankTotals> all(static_cast<std::size_t>(p));
  MPI_Gather(&mine, kFields, MPI_DOUBLE, all.data(), kFields, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  if (!root) return;
  const double frames = o.frames;
  auto per_rank = [&](double RankTotals::*field, double scale) {
    nlohmann::json a = nlohmann::json::array();
    for (const RankTotals& t : all) a.push_back(t.*field / frames * scale);
    return a;
  };
  auto phase = [&](double RankTotals::*field) {
    double most = 0, sum = 0;
    for (const RankTotals& t : all) {
      most = std::max(most, t.*field);
      sum += t.*field;
    }
    nlohmann::ordered_json j;
    j["max_ms_per_frame"] = most / frames * 1e3;
    j["mean_ms_per_frame"] = sum / p / frames * 1e3;
    return j;
  };
  double ghosts = 0, owned = 0;
  for (const RankTotals& t : all) {
    ghosts += t.ghosts;
    owned += t.owned;
  }
  const dist::Options& used = replay.domain().options();
  nlohmann::ordered_json j;
  j["algo"] = o.algo;
  j["scene"] = o.scene.empty() ? "gen:" + o.gen + ":n=" + std::to_string(replay.size()) +
                                     ":seed=" + std::to_string(o.seed)
                               : o.scene;
  j["n"] = replay.size();
  j["world"] = world;
  j["frames"] = o.frames;
  j["ranks"] = p;
  j["decomposition"] = o.bisect
                           ? "bisection"
                           : std::to_string(used.dims[0]) + "x" + std::to_string(used.dims[1]) +
                                 "x" + std::to_string(used.dims[2]);
  j["margin"] = o.margin;
  j["balance_by"] = o.balance_by;
  j["pairs_total"] = total.pairs;
  j["hash_total"] = hex16(total.hash);
  if (replay.has_rays()) {
    j["hits_total"] = hits.hits;
    j["hits_hash_total"] = hex16(hits.hash);
    j["closest_hash_total"] = hex16(hits.closest);
  }
  j["median_frame_ms"] = median(frame_ms);
  j["frame_ms"] = frame_ms;  // rank 0's, each frame (the ranks meet at its end)
  j["load_ms"] = load_s * 1e3;
  j["setup_ms"] = setup_s * 1e3;
  nlohmann::ordered_json phases;
  phases["step"] = phase(&RankTotals::step);
  phases["migration"] = phase(&RankTotals::migration);
  phases["balancing"] = phase(&RankTotals::balancing);
  phases["ghost_exchange"] = phase(&RankTotals::exchange);
  phases["local_pairs"] = phase(&RankTotals::local);
  phases["reduction"] = phase(&RankTotals::reduction);
  phases["rays"] = phase(&RankTotals::rays);
  phases["rays_cpu"] = phase(&RankTotals::rays_cpu);
  j["phases"] = phases;
  j["owned_per_rank"] = per_rank(&RankTotals::owned, 1);
  j["ghosts_per_rank"] = per_rank(&RankTotals::ghosts, 1);
  j["shared_objects"] = all[0].shared / frames;
  j["ghosts_over_owned"] = owned > 0 ? ghosts / owned : 0;
  j["pairs_per_rank"] = per_rank(&RankTotals::pairs, 1);
  j["bytes_per_rank_per_frame"] = per_rank(&RankTotals::bytes, 1);
  j["messages_per_rank_per_frame"] = per_rank(&RankTotals::messages, 1);
  j["load_imbalance_last"] = last_imbalance;
  j["load_imbalance_worst"] = worst_imbalance;
  j["rebalances"] = rebalances;
  j["skin"] = o.skin;
  j["rebuilds"] = rebuilds;
  std::printf("%s\n", j.dump(2).c_str());
}

// check: every scene replayed on one process (rank 0, the oracle structure)
// and over the ranks; each frame's line (pairs, and with rays the hits) must
// agree, and with a sibling .expected file when there is one. With rays,
// the last frame's rays are cast again through closest_hits and any_hits.
struct CheckOptions {
  std::vector<std::string> scenes;
  std::string oracle = "naive";
};

std::vector<std::string> read_expected(const std::string& scene_path) {
  std::vector<std::string> e;
  if (scene_path.size() < 6 || scene_path.substr(scene_path.size() - 6) != ".scene") return e;
  std::ifstream in(scene_path.substr(0, scene_path.size() - 6) + ".expected");
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) e.push_back(line);
  return e;
}

void check(const Common& o, const CheckOptions& c) {
  const dist::Options options = domain_options(o);
  const bool root = world_rank() == 0;
  for (std::string path : c.scenes) {
    // PATH@FRAMES: this scene's own frame count.
    int scene_frames = o.frames;
    if (const auto at = path.rfind('@'); at != std::string::npos) {
      scene_frames = std::atoi(path.c_str() + at + 1);
      path.resize(at);
    }
    // The oracle first, on rank 0 alone.
    std::vector<std::string> want;
    std::vector<FrameDigest> want_pairs;
    std::vector<std::string> expected;
    std::string error;
    int frames = scene_frames;
    if (root) {
      try {
        expected = read_expected(path);
        if (!expected.empty()) frames = std::min<int>(frames, static_cast<int>(expected.size()));
        broadphase::Scene scene = broadphase::read_scene(path);
        const bool rays = scene.has_rays();
        broadphase::Config config;
        config.world = {{0, 0, 0}, {scene.world, scene.world, scene.world}};
        auto bp = broadphase::make_structure(c.oracle, config);
        broadphase::Replay one(*bp, std::move(scene));
        for (int f = 0; f < frames; ++f) {
          const broadphase::FrameResult r = one.next();
          want.push_back(broadphase::frame_line(f, r, rays));
          want_pairs.push_back(r.digest);
        }
      } catch (const std::exception& e) {
        error = path + ": one-process replay failed: " + e.what();
      }
    }
    dist::agree(MPI_COMM_WORLD, error);
    MPI_Bcast(&frames, 1, MPI_INT, 0, MPI_COMM_WORLD);
    mpi_app::MpiReplay replay(MPI_COMM_WORLD, mpi_app::read_share(MPI_COMM_WORLD, path), options,
                              o.skin);
    int rebalances = 0;
    for (int f = 0; f < frames; ++f) {
      const mpi_app::FrameReport r = replay.next();
      rebalances += r.rebalanced ? 1 : 0;
      std::string bad;
      if (root) {
        const auto i = static_cast<std::size_t>(f);
        const std::string line =
            broadphase::frame_line(f, r.digest, replay.has_rays() ? &r.hits : nullptr);
        if (line != want[i])
          bad = path + ": frame " + std::to_string(f) + ": " + std::to_string(world_size()) +
                " ranks give '" + line + "', one process '" + want[i] + "'";
        else if (i < expected.size() && line != expected[i])
          bad = path + ": frame " + std::to_string(f) + ": '" + line + "' differs from the " +
                ".expected file's '" + expected[i] + "'";
      }
      dist::agree(MPI_COMM_WORLD, bad);
    }
    {
      // The last frame again, through the borrowed-arrays entry point.
      const FrameDigest again = replay.digest_through_arrays();
      std::string bad;
      if (root && frames > 0 && !(again == want_pairs[static_cast<std::size_t>(frames - 1)]))
        bad = path + ": the arrays entry point gives " + std::to_string(again.pairs) +
              " pairs at the last frame, one process " +
              std::to_string(want_pairs[static_cast<std::size_t>(frames - 1)].pairs);
      dist::agree(MPI_COMM_WORLD, bad);
    }
    if (frames > 0 && replay.has_rays()) replay.check_ray_entry_points();
    if (root)
      std::printf("ok %s: %d frames, %d ranks, %llu objects, %d rebalances\n", path.c_str(), frames,
                  world_size(), static_cast<unsigned long long>(replay.size()), rebalances);
  }
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  const int rank = world_rank();
  CLI::App app{"broadphase-mpi: the broad phase over MPI ranks (rank 0 prints)"};
  app.require_subcommand(1);
  Common o;
  auto* run_cmd = app.add_subcommand(
      "run", "Replay a scene over the ranks; print each frame's pair count and hash");
  run_cmd->add_option("--scene", o.scene, "Scene file (read by rank 0 and scattered)");
  run_cmd->add_option("--gen", o.gen,
                      "Generate on the ranks instead (counter-based): even, uneven, scaled-even, "
                      "scaled-uneven, decades, all-moving, flat, outside");
  run_cmd->add_option("--n", o.n, "Objects in the generated scene")
      ->check(CLI::Range(0ull, 4294967295ull));
  run_cmd->add_option("--per-rank", o.per_rank, "Objects per rank (weak scaling): n = this * ranks")
      ->check(CLI::Range(0ull, 4294967295ull));
  run_cmd->add_option("--seed", o.seed, "Seed of the generated scene")->default_val(1);
  run_cmd->add_flag("--json", o.json, "One JSON summary (ranks, phases, ghosts, traffic)");
  run_cmd->add_flag("--skip-local", o.skip_local,
                    "Measure the decomposition only: ghosts and traffic, no pairs (lab)");
  add_common(run_cmd, o);

  CheckOptions c;
  auto* check_cmd = app.add_subcommand(
      "check", "Tests: replay scenes on one process and over the ranks, compare every frame");
  check_cmd->add_option("--scene", c.scenes, "Scene files")->required();
  check_cmd->add_option("--oracle", c.oracle, "One-process structure")->default_val("naive");
  add_common(check_cmd, o);

  std::string out;
  auto* gen_cmd = app.add_subcommand("gen", "Write a counter-generated scene file (one process)");
  gen_cmd->add_option("--gen", o.gen, "Kind (as run --gen)")->required();
  gen_cmd->add_option("--n", o.n, "Objects")->required()->check(CLI::Range(0ull, 100000000ull));
  gen_cmd->add_option("--seed", o.seed, "Seed")->default_val(1);
  gen_cmd->add_option("--out", out, "Output scene file")->required();

  int status = 0;
  try {
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      // Every rank parses the same arguments: one prints.
      status = rank == 0 ? app.exit(e) : (e.get_exit_code() == 0 ? 0 : 2);
      MPI_Finalize();
      return status;
    }
    if (run_cmd->parsed()) run(o);
    if (check_cmd->parsed()) check(o, c);
    if (gen_cmd->parsed() && rank == 0)
      broadphase::write_scene(out, broadphase::generate_counter(parse_kind(o.gen), o.n, o.seed));
  } catch (const MpiError& e) {
    // Every rank has it: rank 0 prints, all exit non-zero.
    if (rank == 0) std::fprintf(stderr, "broadphase-mpi: error: %s\n", e.what());
    status = 1;
  } catch (const broadphase::InvalidConfig& e) {
    // Bad options: every rank read the same ones and threw the same.
    if (rank == 0) std::fprintf(stderr, "broadphase-mpi: error: %s\n", e.what());
    status = 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "broadphase-mpi: rank %d: error: %s\n", rank, e.what());
    std::fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  MPI_Finalize();
  return status;
}
