// The lab's building blocks: statistics, batch sizes, scenes and one
// structure measured on one scene.
#include <gtest/gtest.h>

#include <broadphase/detail/median.hpp>
#include <broadphase/naive.hpp>
#include <broadphase/registry.hpp>
#include <chrono>
#include <thread>

#include "budget.hpp"
#include "paper_measure.hpp"
#include "paper_report.hpp"
#include "progress.hpp"
#include "structures.hpp"

namespace broadphase::app {
namespace {

TEST(LabStat, MedianQuartilesAndSpread) {
  const Stat s = summarize({5, 1, 4, 2, 3});
  EXPECT_EQ(s.median, 3);
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.max, 5);
  EXPECT_EQ(s.q1, 2);
  EXPECT_EQ(s.q3, 4);
  EXPECT_EQ(s.reps, 5);
  EXPECT_EQ(summarize({1, 2}).median, 1.5);
  EXPECT_EQ(summarize({}).reps, 0);
}

TEST(LabStat, OneMedianForEveryMeasuringProgram) {
  EXPECT_EQ(detail::median({}), 0);
  EXPECT_EQ(detail::median({7}), 7);
  EXPECT_EQ(detail::median({3, 1, 2}), 2);
  EXPECT_EQ(detail::median({4, 1, 3, 2}), 2.5);
  EXPECT_EQ(detail::median({9, 9, 1, 1}), 5);
  EXPECT_EQ(detail::median({2, 2, 2, 8, 8, 8}), 5);
}

TEST(LabChurn, BatchIsATenthWithinBounds) {
  EXPECT_EQ(churn_batch(50), 5u);
  EXPECT_EQ(churn_batch(20), 4u);
  EXPECT_EQ(churn_batch(3), 3u);
  EXPECT_EQ(churn_batch(6400), 640u);
  EXPECT_EQ(churn_batch(1024000), 1024u);
}

TEST(LabScene, DeterministicAndScaled) {
  const PaperScene a = make_paper_scene(400, false, false, 9);
  const PaperScene b = make_paper_scene(400, false, false, 9);
  EXPECT_EQ(a.scene.objects, b.scene.objects);
  EXPECT_EQ(a.moving, 80u);
  EXPECT_EQ(a.dist, Distribution::uneven);
  const PaperScene even = make_paper_scene(400, true, false, 9);
  EXPECT_NE(even.scene.objects, a.scene.objects);
  const PaperScene scaled = make_paper_scene(51200, true, true, 9);
  EXPECT_EQ(scaled.dist, Distribution::scaled_even);
  EXPECT_NEAR(scaled.scene.world, 2000.0, 1e-9);
}

TEST(LabMeasure, NaiveOnOneScene) {
  const PaperScene ps = make_paper_scene(200, true, false, 3);
  MeasureOptions o;
  o.reps = 3;
  o.min_rep_seconds = 1e-4;
  int ticks = 0;
  const SceneResult r =
      measure_scene(registry(), "naive", false, ps, o, [&ticks](const std::string&) { ++ticks; });
  EXPECT_GT(ticks, 0);
  ASSERT_EQ(r.digests.size(), 4u);  // frame 0 and one per repetition
  ASSERT_EQ(r.query_hits.size(), 3u);
  // Every moving object finds at least itself.
  for (std::uint64_t h : r.query_hits) EXPECT_GE(h, ps.moving);
  std::map<std::string, const Row*> by_test;
  for (const Row& row : r.rows) by_test[row.test] = &row;
  for (const char* t : {"query_time", "query_tests", "insert_time", "remove_time", "memory",
                        "frame_time", "build_time"})
    ASSERT_TRUE(by_test.count(t)) << t;
  EXPECT_EQ(by_test["query_time"]->study_test, 2);
  EXPECT_EQ(by_test["query_tests"]->study_test, 4);
  EXPECT_EQ(by_test["query_tests"]->stat.median, 200);  // naive tests everything
  EXPECT_EQ(by_test["insert_time"]->stat.reps, 3);
  EXPECT_GT(by_test["memory"]->stat.median, 0);
  EXPECT_LE(by_test["frame_time"]->stat.min, by_test["frame_time"]->stat.median);

  // The same scene replayed again gives the same pairs.
  const SceneResult again =
      measure_scene(registry(), "naive", false, ps, o, [](const std::string&) {});
  EXPECT_EQ(again.digests, r.digests);
  EXPECT_EQ(again.query_hits, r.query_hits);
}

TEST(LabMeasure, UnevenRunsNoChurn) {
  const PaperScene ps = make_paper_scene(100, false, false, 3);
  MeasureOptions o;
  o.reps = 1;
  o.min_rep_seconds = 1e-5;
  o.churn = false;
  const SceneResult r = measure_scene(registry(), "naive", false, ps, o, [](const std::string&) {});
  for (const Row& row : r.rows) {
    EXPECT_NE(row.test, "insert_time");
    EXPECT_EQ(row.placement, "uneven");
    if (row.test == "query_time") {
      EXPECT_EQ(row.study_test, 1);
    }
  }
}

// The lean path on the study's scenes: the pairs of every frame are the
// naive oracle's, through the same motion, frame 0 (the build) included.
TEST(LabMeasure, ArraysFramesAgreeWithNaive) {
  for (const std::uint64_t seed : {3ull, 11ull}) {
    for (const std::size_t n : {50u, 400u, 1600u}) {
      for (const bool even : {true, false}) {
        SCOPED_TRACE("seed " + std::to_string(seed) + ", N=" + std::to_string(n) +
                     (even ? ", even" : ", uneven"));
        const PaperScene ps = make_paper_scene(n, even, false, seed);
        MeasureOptions o;
        o.reps = 4;
        o.min_rep_seconds = 1e-5;
        o.churn = false;
        int ticks = 0;
        const SceneResult a = measure_arrays(ps, o, [&ticks](const std::string&) { ++ticks; });
        const SceneResult ref =
            measure_scene(registry(), "naive", false, ps, o, [](const std::string&) {});
        EXPECT_GT(ticks, 0);
        ASSERT_EQ(a.digests.size(), 5u);  // frame 0 and one per repetition
        EXPECT_EQ(a.digests, ref.digests);
        EXPECT_TRUE(a.query_hits.empty());
        std::map<std::string, const Row*> by_test;
        for (const Row& row : a.rows) {
          EXPECT_EQ(row.structure, kArraysSeries);
          EXPECT_EQ(row.placement, even ? "even" : "uneven");
          EXPECT_EQ(row.n, n);
          by_test[row.test] = &row;
        }
        EXPECT_EQ(by_test.size(), 4u);
        for (const char* t : {"frame_time", "build_time", "memory", "memory_with_arrays"})
          ASSERT_TRUE(by_test.count(t)) << t;
        EXPECT_EQ(by_test["frame_time"]->stat.reps, 4);
        EXPECT_EQ(by_test["frame_time"]->unit, "ms");
        EXPECT_GT(by_test["memory"]->stat.median, 0);
        // The caller's arrays: x, y, z and radius, 8 bytes each per sphere.
        EXPECT_EQ(by_test["memory_with_arrays"]->stat.median - by_test["memory"]->stat.median,
                  32.0 * static_cast<double>(n));
      }
    }
  }
}

// A structure with only the lean path's rows: no line in the tables of
// the tests it does not run, a line in the frame-time and memory tables.
TEST(LabReport, TheLeanPathOnlyWhereItHasRows) {
  PaperResults res;
  res.info.structures = {"naive", kArraysSeries, "grid-dense"};
  res.info.peers = {false, false, false};
  res.info.registered = {"naive", "grid-dense"};
  res.info.study_sizes = {50};
  res.skips.push_back({"grid-dense", 50, 3, 1, "projected 3 s"});
  auto add = [&res](const std::string& s, const std::string& test, double v) {
    Row r;
    r.structure = s;
    r.test = test;
    r.placement = "even";
    r.dist = "even";
    r.n = 50;
    r.stat.median = v;
    res.rows.push_back(r);
  };
  for (const char* t : {"query_time", "query_tests", "insert_time", "remove_time", "frame_time"})
    add("naive", t, 1);
  add("naive", "memory", 5000);
  add(kArraysSeries, "frame_time", 0.5);
  add(kArraysSeries, "memory", 2000);
  add(kArraysSeries, "memory_with_arrays", 3600);
  const std::string md = report_markdown(res);
  auto between = [&md](const std::string& from, const std::string& to) {
    const std::size_t a = md.find(from);
    EXPECT_NE(a, std::string::npos) << from;
    return md.substr(a, md.find(to, a) - a);
  };
  const std::string test1 = between("### Test 1", "### Test 2");
  EXPECT_EQ(test1.find("| arrays"), std::string::npos) << test1;
  EXPECT_NE(test1.find("| naive |"), std::string::npos) << test1;
  EXPECT_NE(test1.find("| grid-dense | skip"), std::string::npos) << "a skipped line stays";
  const std::string frames = between("### Frame time, even placement", "### Frame time, uneven");
  EXPECT_NE(frames.find("| arrays | 0.50 |"), std::string::npos) << frames;
  const std::string memory = between("## Memory", "## Beyond the study");
  EXPECT_NE(memory.find("| arrays | 40.0 |"), std::string::npos) << memory;
  EXPECT_NE(memory.find("| arrays with the caller's arrays | 72.0 |"), std::string::npos) << memory;
  EXPECT_EQ(memory.find("naive with the caller's arrays"), std::string::npos) << memory;
}

TEST(LabReport, StudyFormulas) {
  EXPECT_EQ(study_memory_formula("naive", 100), 404);
  EXPECT_EQ(study_memory_formula("octree-paper", 100), 44860);
  EXPECT_EQ(study_memory_formula("hgrid-paper", 100), 38652);
  EXPECT_LT(study_memory_formula("grid-dense", 100), 0);
}

TEST(LabReport, FindingsNameWhatIsMissing) {
  PaperResults res;
  res.info.structures = {"naive"};
  res.info.peers = {false};
  res.info.registered = {"naive"};
  res.info.study_sizes = {50};
  const std::string md = report_markdown(res);
  EXPECT_NE(md.find("`octree-paper` is not registered in this build"), std::string::npos);
  EXPECT_NE(md.find("Cannot check"), std::string::npos);
  EXPECT_NE(md.find("Plots were skipped"), std::string::npos);
}

TEST(LabReport, MismatchIsAnErrorInRed) {
  PaperResults res;
  res.info.structures = {"naive"};
  res.info.peers = {false};
  res.mismatches.push_back({50, "even", "frame 1", "naive", "1 pairs", "2 pairs", "other"});
  const std::string md = report_markdown(res);
  EXPECT_NE(md.find("color:red"), std::string::npos);
  EXPECT_NE(md.find("MISMATCH"), std::string::npos);
}

// Synthetic results shaped like the study's: every finding must be found.
PaperResults study_shaped() {
  PaperResults res;
  res.info.structures = {"naive", "octree-paper", "hgrid-paper", "peer-x"};
  res.info.peers = {false, false, false, true};
  res.info.registered = res.info.structures;
  res.info.study_sizes = {50, 100, 200, 400, 800, 1600, 3200, 6400};
  auto add = [&res](const std::string& s, const std::string& test, const std::string& pl,
                    std::size_t n, double v) {
    Row r;
    r.structure = s;
    r.peer = s == "peer-x";
    r.test = test;
    r.placement = pl;
    r.n = n;
    r.stat = summarize({v, v * 1.1, v * 0.9});
    res.rows.push_back(r);
  };
  for (std::size_t n : res.info.study_sizes) {
    const double x = static_cast<double>(n);
    for (const char* pl : {"uneven", "even"}) {
      const double even = pl[0] == 'e' ? 1.5 : 1.0;
      add("naive", "query_tests", pl, n, x);
      add("octree-paper", "query_tests", pl, n, 20 * even + x / 50);
      add("hgrid-paper", "query_tests", pl, n, 10 + x / 100);
      add("naive", "query_time", pl, n, x);
      // The octree is faster up to 200 objects, the hgrid from 400 on.
      add("octree-paper", "query_time", pl, n, n <= 200 ? 50 : 400 + x / 10);
      add("hgrid-paper", "query_time", pl, n, 100 + x / 100);
    }
    add("naive", "insert_time", "even", n, 10);
    add("octree-paper", "insert_time", "even", n, 100);
    add("hgrid-paper", "insert_time", "even", n, 300);
    add("naive", "remove_time", "even", n, 100);
    add("octree-paper", "remove_time", "even", n, 200);
    add("hgrid-paper", "remove_time", "even", n, 20);
    add("naive", "frame_time", "even", n, x / 100);
    add("peer-x", "frame_time", "even", n, x / 400);
  }
  return res;
}

TEST(LabReport, StudyShapedResultsReproduceEveryFinding) {
  const std::string md = report_markdown(study_shaped());
  std::size_t reproduced = 0;
  for (std::size_t at = md.find("| **Reproduced** |"); at != std::string::npos;
       at = md.find("| **Reproduced** |", at + 1))
    ++reproduced;
  EXPECT_EQ(reproduced, 5u) << md.substr(md.find("## The study's findings"), 3000);
  EXPECT_NE(md.find("the hgrid is faster from N=400"), std::string::npos);
  // Versus peers: naive takes 4 times the fastest peer's frame time.
  EXPECT_NE(md.find("### Versus peers"), std::string::npos);
  EXPECT_NE(md.find("| naive | 4.00 |"), std::string::npos)
      << md.substr(md.find("### Versus peers"), 1500);
}

TEST(LabReport, ContraryResultsAreNotReproduced) {
  PaperResults res = study_shaped();
  for (Row& r : res.rows)
    if (r.structure == "hgrid-paper" && r.test == "query_tests") r.stat.median *= 1000;
  const std::string md = report_markdown(res);
  EXPECT_NE(md.find("fewest narrow-phase tests at every N | **Not reproduced**"),
            std::string::npos);
}

TEST(LabProgress, FormatsSeconds) {
  EXPECT_EQ(ProgressBar::format_seconds(42), "42s");
  EXPECT_EQ(ProgressBar::format_seconds(185), "3m05s");
  EXPECT_EQ(ProgressBar::format_seconds(3720), "1h02m");
  EXPECT_EQ(ProgressBar::format_seconds(-1), "?");
}

TEST(LabBudget, AStepPastItsPlanIsNeverNearlyDone) {
  // The progress line's estimate of what is left: from the plan while the
  // step is within it, from the rate of its fraction done when that says
  // more, and never zero while a step past its plan runs.
  RunBudget b(100, 4);
  b.begin("quiet", 0.01);
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  const double spent = b.step_spent();
  ASSERT_GT(spent, 0.05);
  EXPECT_GE(b.step_left(0), 0.25 * spent);    // over its plan, no fraction to go by
  EXPECT_GE(b.step_left(0.5), spent * 0.99);  // half done: as much again
  EXPECT_GE(b.step_left(0.99), 0.0);
  EXPECT_DOUBLE_EQ(b.estimate_left(2, 10), 2 + 10 + 4);  // no step ended: pace 1
  const double took = b.end();
  EXPECT_GE(took, spent);
  // That step ran far over its plan: the steps after it are slowed by it.
  EXPECT_GT(b.pace(), 2);
  EXPECT_GT(b.estimate_left(0, 10), 10 * 2);
  EXPECT_GE(b.pace(50), 50);
}

TEST(LabBudget, SaysHowFarOverThePlan) {
  EXPECT_EQ(over_text(1.4, "its plan"), "40% over its plan");
  EXPECT_EQ(over_text(2.5, "its 20s"), "2.5 times its 20s");
}

}  // namespace
}  // namespace broadphase::app
