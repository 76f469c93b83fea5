#include "paper_measure.hpp"

#include <algorithm>
#include <broadphase/arrays/arrays.hpp>
#include <broadphase/scenes/array_caller.hpp>
#include <broadphase/scenes/replay.hpp>
#include <chrono>
#include <numeric>
#include <stdexcept>

#include "lab_data.hpp"

namespace broadphase::app {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// The cost of reading the clock twice, subtracted from every timed region
// so that regions of a few dozen nanoseconds per object are not inflated.
double clock_overhead() {
  static const double overhead = [] {
    double best = 1;
    for (int i = 0; i < 2000; ++i) {
      const auto t0 = Clock::now();
      best = std::min(best, since(t0));
    }
    return best;
  }();
  return overhead;
}

// Rounds shorter than this in all are repeated at least three times.
constexpr double kShortRound = 0.05;

double timed_part(Clock::time_point t0) { return std::max(0.0, since(t0) - clock_overhead()); }

}  // namespace

Stat summarize(std::vector<double> v) {
  Stat s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  auto at = [&v](double q) {
    const double pos = q * static_cast<double>(v.size() - 1);
    const std::size_t i = static_cast<std::size_t>(pos);
    const double f = pos - static_cast<double>(i);
    return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
  };
  s.median = at(0.5);
  s.q1 = at(0.25);
  s.q3 = at(0.75);
  s.min = v.front();
  s.max = v.back();
  s.reps = static_cast<int>(v.size());
  return s;
}

CellCosts& CellCosts::operator+=(const CellCosts& o) {
  build += o.build;
  frame += o.frame;
  pass += o.pass;
  churn += o.churn;
  total += o.total;
  return *this;
}

PaperScene make_paper_scene(std::size_t n, bool even, bool scaled, std::uint64_t seed) {
  PaperScene ps;
  ps.n = n;
  ps.even = even;
  ps.dist = scaled ? (even ? Distribution::scaled_even : Distribution::scaled_uneven)
                   : (even ? Distribution::even : Distribution::uneven);
  // One seed per size and placement, so that adding a size leaves the
  // other scenes as they were.
  ps.seed = splitmix64(seed ^ splitmix64(n * 4 + (even ? 1 : 0) + (scaled ? 2 : 0)));
  ps.scene = generate(ps.dist, n, ps.seed);
  for (std::size_t i = 0; i < ps.scene.size(); ++i) ps.moving += ps.scene.is_moving(i) ? 1 : 0;
  return ps;
}

std::size_t churn_batch(std::size_t n) {
  return std::clamp<std::size_t>(n / 10, std::min<std::size_t>(4, n), 1024);
}

namespace {

// A row of one metric of lab/metrics.json, which gives its unit and the
// study's test number (an unlisted name throws: the list comes first).
Row make_row(const std::string& structure, bool peer, const PaperScene& ps, const std::string& test,
             std::vector<double> samples, const std::string& note) {
  const std::string placement = ps.even ? "even" : "uneven";
  const Metric& m = metric(test);
  Row r;
  r.structure = structure;
  r.peer = peer;
  r.test = test;
  r.study_test = m.study_test_for(placement);
  r.placement = placement;
  r.dist = std::string(to_string(ps.dist));
  r.n = ps.n;
  r.world = ps.scene.world;
  r.unit = m.unit;
  r.stat = summarize(std::move(samples));
  r.note = note;
  return r;
}

}  // namespace

SceneResult measure_scene(const Registry& registry, const std::string& structure, bool peer,
                          const PaperScene& ps, const MeasureOptions& o,
                          const std::function<void(const std::string&)>& tick) {
  SceneResult out;
  const auto t_cell = Clock::now();
  const std::size_t n = ps.n;
  const double L = ps.scene.world;
  // A row of one metric of lab/metrics.json (make_row).
  auto add_row = [&](const std::string& test, std::vector<double> samples,
                     const std::string& note = {}) {
    out.rows.push_back(make_row(structure, peer, ps, test, std::move(samples), note));
  };
  auto over_cap = [&] { return since(t_cell) > 1.5 * o.cell_cap_seconds; };
  // A timed loop goes on until it has run the minimum time, and for at
  // least three rounds unless they are long (then one preempted round
  // cannot be the median).
  auto enough = [&o](double spent, std::size_t rounds) {
    return spent < o.min_rep_seconds || (rounds < 3 && spent < kShortRound);
  };

  Config config;
  config.world = {{0, 0, 0}, {L, L, L}};
  config.expected_objects = n;
  auto bp = registry.make(structure, config);

  tick("build");
  auto t0 = Clock::now();
  Replay replay(*bp, ps.scene);
  out.costs.build = since(t0);
  add_row("build_time",
          {replay.build_seconds() / static_cast<double>(std::max<std::size_t>(n, 1)) * 1e9});

  std::vector<std::uint32_t> moving;
  for (std::size_t i = 0; i < n; ++i)
    if (ps.scene.is_moving(i)) moving.push_back(static_cast<std::uint32_t>(i));

  out.digests.push_back(replay.next().digest);
  std::vector<double> frame_ms, frame_wall, query_ns, query_tests;
  double pass_wall = 0;
  int reps_done = 0;
  for (int rep = 0; rep < o.reps; ++rep) {
    tick("frame " + std::to_string(rep + 1) + "/" + std::to_string(o.reps));
    t0 = Clock::now();
    const FrameResult fr = replay.next();
    frame_wall.push_back(since(t0));
    frame_ms.push_back(fr.seconds() * 1e3);
    out.digests.push_back(fr.digest);

    // Tests 1-4: every moving object queries with its own sphere, on the
    // positions of the frame just evaluated. Small scenes repeat the pass
    // until the clock has something to measure.
    tick("queries " + std::to_string(rep + 1) + "/" + std::to_string(o.reps));
    std::uint64_t hits = 0, tests = 0;
    std::vector<double> pass_times;
    double spent = 0;
    const auto& objects = replay.scene().objects;
    do {
      std::uint64_t pass_hits = 0, pass_tests = 0;
      auto visitor = [&pass_hits](Handle) {
        ++pass_hits;
        return true;
      };
      t0 = Clock::now();
      for (std::uint32_t i : moving) pass_tests += bp->query(objects[i], visitor).tests;
      pass_times.push_back(timed_part(t0));
      spent += pass_times.back();
      if (pass_times.size() == 1) {
        hits = pass_hits;
        tests = pass_tests;
      }
    } while (!moving.empty() && enough(spent, pass_times.size()));
    // The median pass, not the mean: on a shared machine one preempted pass
    // would otherwise count for all the others.
    const double pass = summarize(pass_times).median;
    pass_wall += pass;
    const double m = static_cast<double>(std::max<std::size_t>(moving.size(), 1));
    query_ns.push_back(pass / m * 1e9);
    query_tests.push_back(static_cast<double>(tests) / m);
    out.query_hits.push_back(hits);
    ++reps_done;
    if (over_cap() && rep + 1 < o.reps) {
      out.note = "stopped after " + std::to_string(reps_done) + " of " + std::to_string(o.reps) +
                 " reps: over the time cap";
      break;
    }
  }
  out.costs.frame = summarize(frame_wall).median;
  out.costs.pass = reps_done > 0 ? pass_wall / reps_done : 0;
  add_row("frame_time", frame_ms, out.note);
  add_row("query_time", query_ns, out.note);
  add_row("query_tests", query_tests, out.note);
  add_row("memory", {static_cast<double>(bp->memory_bytes())});

  if (o.churn && n > 0) {
    // Tests 5 and 6: remove a batch of k random objects, then insert the
    // same objects again (the structure holds between N - k and N objects).
    // The removals are timed for Test 6, the insertions for Test 5.
    std::vector<Handle> handles(n);
    for (std::size_t i = 0; i < n; ++i) handles[i] = replay.handle(i);
    const Scene& scene = replay.scene();
    const std::size_t k = churn_batch(n);
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    Rng rng(ps.seed ^ 0x5eed);
    std::vector<double> insert_ns, remove_ns;
    double batch_wall = 0;
    int batches_total = 0;
    const std::string churn_note = o.reps > reps_done ? out.note : std::string{};
    for (int rep = 0; rep < reps_done; ++rep) {
      tick("insert/remove " + std::to_string(rep + 1) + "/" + std::to_string(reps_done));
      std::vector<double> removing, inserting;
      double spent = 0;
      const auto t_rep = Clock::now();
      do {
        for (std::size_t j = 0; j < k; ++j) std::swap(order[j], order[j + rng.below(n - j)]);
        t0 = Clock::now();
        for (std::size_t j = 0; j < k; ++j) bp->remove(handles[order[j]]);
        removing.push_back(timed_part(t0));
        t0 = Clock::now();
        for (std::size_t j = 0; j < k; ++j) {
          const std::uint32_t id = order[j];
          handles[id] = bp->insert(scene.objects[id], id,
                                   scene.is_moving(id) ? Motion::dynamic : Motion::fixed);
        }
        inserting.push_back(timed_part(t0));
        spent += removing.back() + inserting.back();
      } while (enough(spent, removing.size()));
      batch_wall += since(t_rep);
      batches_total += static_cast<int>(removing.size());
      // Median batch, as for the queries: robust to a preempted batch.
      const double per = 1e9 / static_cast<double>(k);
      insert_ns.push_back(summarize(inserting).median * per);
      remove_ns.push_back(summarize(removing).median * per);
    }
    out.costs.churn = batches_total > 0 ? batch_wall / batches_total : 0;
    add_row("insert_time", insert_ns, churn_note);
    add_row("remove_time", remove_ns, churn_note);
  }
  out.costs.total = since(t_cell);
  return out;
}

SceneResult measure_arrays(const PaperScene& ps, const MeasureOptions& o,
                           const std::function<void(const std::string&)>& tick) {
  SceneResult out;
  const auto t_cell = Clock::now();
  auto add_row = [&](const std::string& test, std::vector<double> samples,
                     const std::string& note = {}) {
    out.rows.push_back(make_row(kArraysSeries, false, ps, test, std::move(samples), note));
  };
  ArrayCaller caller(ps.scene);
  PairTracker tracker;
  const Objects objects = caller.objects();
  std::vector<IndexPair> pairs;
  // One call: timed from the call to its return, the digest taken after,
  // as Replay::next() times update + find_pairs and hashes outside.
  auto call = [&](const Changes& changes, double& seconds) {
    pairs.clear();
    const auto t0 = Clock::now();
    tracker.find_pairs(objects, pairs, changes);
    seconds = since(t0);
    FrameDigest d;
    for (const IndexPair& p : pairs) d.add(p.i, p.j);
    out.digests.push_back(d);
  };

  tick("build");
  double build = 0;
  call(Changes::everything(), build);  // frame 0: the build, not a frame
  out.costs.build = build;
  add_row("build_time", {build / static_cast<double>(std::max<std::size_t>(ps.n, 1)) * 1e9});

  std::vector<double> frame_ms, frame_wall;
  int reps_done = 0;
  for (int rep = 0; rep < o.reps; ++rep) {
    tick("frame " + std::to_string(rep + 1) + "/" + std::to_string(o.reps));
    const auto t_frame = Clock::now();
    // The replay's motion (ArrayCaller::step moves the movers exactly as
    // step(Scene&) does), not timed, as the replay's is not.
    if (const std::size_t bad = caller.step(); bad != SIZE_MAX)
      throw std::runtime_error("frame " + std::to_string(rep + 1) + ": object " +
                               std::to_string(bad) +
                               " moves beyond the range of doubles (its motion overflows)");
    double seconds = 0;
    call(Changes::only(caller.movers()), seconds);
    frame_wall.push_back(since(t_frame));
    frame_ms.push_back(seconds * 1e3);
    ++reps_done;
    if (since(t_cell) > 1.5 * o.cell_cap_seconds && rep + 1 < o.reps) {
      out.note = "stopped after " + std::to_string(reps_done) + " of " + std::to_string(o.reps) +
                 " reps: over the time cap";
      break;
    }
  }
  out.costs.frame = summarize(frame_wall).median;
  add_row("frame_time", frame_ms, out.note);
  // Own bytes (the tracker's index and candidate lists), and with the
  // caller's arrays the tracker reads (the handle structures hold their
  // own copy of every shape, so the second is the like-for-like figure).
  const double own = static_cast<double>(tracker.memory_bytes());
  add_row("memory", {own});
  add_row("memory_with_arrays", {own + static_cast<double>(caller.bytes())});
  out.costs.total = since(t_cell);
  return out;
}

}  // namespace broadphase::app
