// paper's step record: what a resumed run gets back, and that a step's
// files reach the output directory only when the step is done.
#include <gtest/gtest.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "paper_steps.hpp"

namespace broadphase::app {
namespace {

namespace fs = std::filesystem;

class PaperStepsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("broadphase-steps-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  static std::string read(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  fs::path dir_;
};

TEST_F(PaperStepsTest, TheStudyComesBackWhole) {
  PaperResults res;
  Row row;
  row.structure = "grid-hashed:cell=2.5";
  row.test = "query_time";
  row.study_test = 1;
  row.placement = "even";
  row.dist = "even";
  row.n = 1600;
  row.world = 0.1 + 0.2;  // not a short decimal: must come back bit for bit
  row.unit = "ns";
  row.stat = {1.25e-7, 1e-300, 3.5, 2, 3, 5};
  row.note = "a \"quoted\", note\n";
  res.rows = {row};
  res.skips = {{"naive", 409600, 12.5, 60, "projected 12 s"}};
  res.mismatches = {{50, "uneven", "frame 3", "octree", "4 pairs", "5 pairs", "naive"}};
  SceneSummary sum;
  sum.n = 50;
  sum.placement = "even";
  sum.dist = "even";
  sum.world = 100;
  sum.moving = 5;
  sum.seed = 18446744073709551615ull;
  sum.frames = {{7, 0xfedcba9876543210ull}, {0, 0}};
  sum.structures = 3;
  res.scenes = {sum};
  res.comparisons = 42;
  res.info.study_seconds = 12.75;
  {
    PaperSteps s = PaperSteps::start(dir_, {{"quick", true}});
    EXPECT_NE(read(dir_ / "RUN-INCOMPLETE").find("Steps done: none"), std::string::npos);
    s.save_study(res);
  }
  EXPECT_NE(read(dir_ / "RUN-INCOMPLETE").find("  study"), std::string::npos);
  EXPECT_EQ(PaperSteps::recorded_options(dir_).value("quick", false), true);
  const PaperSteps s = PaperSteps::resume(dir_);
  PaperResults back;
  ASSERT_TRUE(s.load_study(back));
  ASSERT_EQ(back.rows.size(), 1u);
  const Row& r = back.rows[0];
  EXPECT_EQ(r.structure, row.structure);
  EXPECT_EQ(r.test, row.test);
  EXPECT_EQ(r.study_test, 1);
  EXPECT_EQ(r.n, 1600u);
  EXPECT_EQ(r.world, row.world);
  EXPECT_EQ(r.stat.median, row.stat.median);
  EXPECT_EQ(r.stat.min, row.stat.min);
  EXPECT_EQ(r.stat.reps, 5);
  EXPECT_EQ(r.note, row.note);
  ASSERT_EQ(back.skips.size(), 1u);
  EXPECT_EQ(back.skips[0].reason, "projected 12 s");
  EXPECT_EQ(back.skips[0].n, 409600u);
  ASSERT_EQ(back.mismatches.size(), 1u);
  EXPECT_EQ(back.mismatches[0].got, "4 pairs");
  EXPECT_EQ(back.mismatches[0].reference, "naive");
  ASSERT_EQ(back.scenes.size(), 1u);
  EXPECT_EQ(back.scenes[0].seed, sum.seed);
  EXPECT_EQ(back.scenes[0].frames, sum.frames);
  EXPECT_EQ(back.scenes[0].structures, 3u);
  EXPECT_EQ(back.comparisons, 42u);
  EXPECT_EQ(back.info.study_seconds, 12.75);
}

TEST_F(PaperStepsTest, AnExperimentsFilesArriveWhenItIsDone) {
  int runs = 0;
  const LabExperiment write_two = [&](const LabContext& ctx) {
    ++runs;
    EXPECT_NE(ctx.out_dir, dir_) << "an experiment writes into its staging directory";
    std::ofstream(ctx.out_dir / "sweep.csv") << "a,b\n";
    fs::create_directories(ctx.out_dir / "scenes");
    std::ofstream(ctx.out_dir / "scenes" / "x.scene") << "scene";
    EXPECT_FALSE(fs::exists(dir_ / "sweep.csv"));
    return std::string("## Sweep\n");
  };
  {
    PaperSteps s = PaperSteps::start(dir_, {});
    EXPECT_EQ(s.experiment("cell-size sweep", LabContext{}, write_two), "## Sweep\n");
    EXPECT_TRUE(s.done("cell-size sweep"));
  }
  EXPECT_EQ(read(dir_ / "sweep.csv"), "a,b\n");
  EXPECT_EQ(read(dir_ / "scenes" / "x.scene"), "scene");
  PaperSteps s = PaperSteps::resume(dir_);
  EXPECT_EQ(s.experiment("cell-size sweep", LabContext{}, write_two), "## Sweep\n");
  EXPECT_EQ(runs, 1) << "a step done is not redone on resume";
}

TEST_F(PaperStepsTest, AFailedExperimentLeavesNothingAndIsNotDone) {
  PaperSteps s = PaperSteps::start(dir_, {});
  const LabExperiment half = [](const LabContext& ctx) -> std::string {
    std::ofstream(ctx.out_dir / "half.csv") << "a,b\n1,";
    throw std::runtime_error("stopped");
  };
  EXPECT_THROW(s.experiment("tunneling", LabContext{}, half), std::runtime_error);
  EXPECT_FALSE(fs::exists(dir_ / "half.csv"));
  EXPECT_FALSE(s.done("tunneling"));
  s.finish({"tunneling"});
  EXPECT_TRUE(fs::exists(dir_ / "RUN-INCOMPLETE"));
  EXPECT_FALSE(s.complete());
  EXPECT_EQ(s.experiment("tunneling", LabContext{}, [](const LabContext&) { return "ok"; }), "ok");
  s.finish({"tunneling"});
  EXPECT_TRUE(s.complete());
  EXPECT_FALSE(fs::exists(dir_ / "RUN-INCOMPLETE"));
}

TEST_F(PaperStepsTest, AnUnwritableDirectoryIsRefusedWithTheReason) {
  std::ofstream(dir_ / "regular") << "";
  try {
    PaperSteps::start(dir_ / "regular", {});
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("Not a directory"), std::string::npos) << e.what();
  }
  EXPECT_THROW(PaperSteps::recorded_options(dir_), std::runtime_error);
}

// A small `paper` run, in process (no experiments are linked into this
// test): the lean path is a series of its own, with frame-time and memory
// rows at every size and placement, and its pairs are checked against the
// other structures' on every frame of every scene.
TEST_F(PaperStepsTest, ASmallRunMeasuresTheLeanPathAndChecksItsPairs) {
  const fs::path out = dir_ / "run";
  CLI::App app;
  add_paper_command(app);
  // No spaces in the path (a temporary directory and the test's name).
  const std::string args =
      "paper --quick --algos naive,grid-hashed,arrays --no-peers --max-n 800 "
      "--budget 20 --out " +
      out.string();
  std::string error;
  try {
    app.parse(args);
  } catch (const std::exception& e) {
    error = e.what();  // a disagreement: results.json below says which
  }
  const nlohmann::json j = nlohmann::json::parse(read(out / "results.json"));
  EXPECT_EQ(error, "");
  EXPECT_TRUE(j.at("mismatches").empty()) << j.at("mismatches").dump(1);
  EXPECT_GT(j.at("comparisons").get<std::size_t>(), 0u);
  const std::vector<std::size_t> sizes{50, 100, 200, 400, 800};
  ASSERT_EQ(j.at("scenes").size(), 2 * sizes.size());
  for (const auto& scene : j.at("scenes")) {
    // naive, grid-hashed and arrays were compared on every frame.
    EXPECT_EQ(scene.at("structures"), 3) << scene.dump();
    EXPECT_EQ(scene.at("frames").size(), 4u) << "frame 0 and one per repetition";
  }
  std::map<std::string, std::set<std::string>> tests_of;
  std::map<std::pair<std::string, std::size_t>, double> memory;
  std::size_t frame_rows = 0;
  for (const auto& r : j.at("rows")) {
    const std::string s = r.at("structure"), test = r.at("test");
    tests_of[s].insert(test);
    if (s != "arrays") continue;
    EXPECT_FALSE(r.at("peer").get<bool>());
    if (test == "frame_time") {
      ++frame_rows;
      EXPECT_GT(r.at("median").get<double>(), 0) << r.dump();
      EXPECT_EQ(r.at("reps"), 3) << r.dump();
    }
    if (r.at("placement") == "even" && (test == "memory" || test == "memory_with_arrays"))
      memory[{test, r.at("n").get<std::size_t>()}] = r.at("median").get<double>();
  }
  EXPECT_EQ(frame_rows, 2 * sizes.size());
  EXPECT_EQ(tests_of["arrays"],
            (std::set<std::string>{"build_time", "frame_time", "memory", "memory_with_arrays"}));
  EXPECT_EQ(tests_of["naive"].count("memory_with_arrays"), 0u);
  for (std::size_t n : sizes)
    EXPECT_EQ((memory[{"memory_with_arrays", n}] - memory[{"memory", n}]), 32.0 * n) << n;
  const std::string report = read(out / "REPORT.md");
  EXPECT_NE(report.find("| arrays with the caller's arrays |"), std::string::npos);
  const std::size_t frames = report.find("### Frame time, even placement");
  ASSERT_NE(frames, std::string::npos);
  EXPECT_NE(report.find("| arrays |", frames), std::string::npos);
  const std::size_t test1 = report.find("### Test 1");
  ASSERT_NE(test1, std::string::npos);
  EXPECT_EQ(report.substr(test1, report.find("### Test 2") - test1).find("| arrays"),
            std::string::npos)
      << "no line of dashes for the tests the lean path does not run";
}

TEST_F(PaperStepsTest, TheLeanPathTakesNoOptions) {
  CLI::App app;
  add_paper_command(app);
  const std::string args = "paper --algos arrays:threads=2 --out " + (dir_ / "x").string();
  try {
    app.parse(args);
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("takes no options"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace broadphase::app
