#include "paper_report.hpp"

#include <unistd.h>

#include <algorithm>
#include <broadphase/scenes/output_file.hpp>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <tuple>

namespace broadphase::app {

namespace {

constexpr const char* kNaive = "naive";
constexpr const char* kOctree = "octree-paper";
constexpr const char* kHgrid = "hgrid-paper";

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && s[i] == ' ') ++i;
  return s.substr(i);
}

// The first line of a command's output, or "" when it cannot be run.
std::string shell_line(const std::string& cmd) {
  std::FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return {};
  char buf[512];
  std::string out;
  if (std::fgets(buf, sizeof buf, p) != nullptr) out = buf;
  pclose(p);
  return trim(out);
}

std::string field_of(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) == 0) {
      const std::size_t colon = line.find(':');
      if (colon != std::string::npos) return trim(line.substr(colon + 1));
    }
  }
  return {};
}

std::string command_line() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string out;
  std::size_t start = 0;
  while (start < all.size()) {
    std::size_t end = all.find('\0', start);
    if (end == std::string::npos) end = all.size();
    std::string arg = all.substr(start, end - start);
    if (arg.empty() || arg.find_first_of(" '\"$\\") != std::string::npos) {
      std::string q = "'";
      for (char c : arg) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
      arg = q + "'";
    }
    out += (out.empty() ? "" : " ") + arg;
    start = end + 1;
  }
  return out.empty() ? "broadphase paper" : out;
}

std::string number(double v) {
  char buf[32];
  const double a = std::fabs(v);
  if (v == 0) return "0";
  if (a >= 100000)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else if (a >= 100)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else if (a >= 10)
    std::snprintf(buf, sizeof buf, "%.1f", v);
  else if (a >= 0.1)
    std::snprintf(buf, sizeof buf, "%.2f", v);
  else
    std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

std::string ratio(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, v >= 10 ? "%.0f×" : "%.2g×", v);
  return buf;
}

std::string size_label(std::size_t n) {
  std::string s = std::to_string(n);
  for (int i = static_cast<int>(s.size()) - 3; i > 0; i -= 3)
    s.insert(static_cast<std::size_t>(i), " ");
  return s;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

std::string red(const std::string& s) { return "<span style=\"color:red\">**" + s + "**</span>"; }

// The results of a run, indexed for the tables.
class Index {
 public:
  explicit Index(const PaperResults& r) : r_(r) {
    for (const Row& row : r.rows) {
      rows_[{row.structure, row.test, row.placement, row.n}] = &row;
      tests_[row.structure].insert(row.test);
    }
    for (const Skip& s : r.skips) skipped_.insert({s.structure, s.n});
    for (const Mismatch& m : r.mismatches) wrong_.insert({m.structure, m.n});
    sizes_ = r.info.study_sizes;
    sizes_.insert(sizes_.end(), r.info.scaled_sizes.begin(), r.info.scaled_sizes.end());
  }
  std::optional<double> get(const std::string& s, const std::string& test, const std::string& pl,
                            std::size_t n) const {
    const auto it = rows_.find({s, test, pl, n});
    if (it == rows_.end()) return std::nullopt;
    return it->second->stat.median;
  }
  const Row* row(const std::string& s, const std::string& test, const std::string& pl,
                 std::size_t n) const {
    const auto it = rows_.find({s, test, pl, n});
    return it == rows_.end() ? nullptr : it->second;
  }
  bool skipped(const std::string& s, std::size_t n) const { return skipped_.count({s, n}) > 0; }
  bool wrong(const std::string& s, std::size_t n) const { return wrong_.count({s, n}) > 0; }
  // False for a structure that ran but never measures `test` (the lean
  // path has no queries, insertions or removals): its table line would be
  // dashes only. A structure with no rows at all (skipped, failed) keeps
  // its line, which says so.
  bool measures(const std::string& s, const std::string& test) const {
    const auto it = tests_.find(s);
    return it == tests_.end() || it->second.count(test) > 0;
  }
  /// True when `s` has at least one row of `test`.
  bool has_rows(const std::string& s, const std::string& test) const {
    const auto it = tests_.find(s);
    return it != tests_.end() && it->second.count(test) > 0;
  }
  bool has(const std::string& s) const {
    return std::find(r_.info.structures.begin(), r_.info.structures.end(), s) !=
           r_.info.structures.end();
  }
  bool is_scaled(std::size_t n) const {
    return std::find(r_.info.scaled_sizes.begin(), r_.info.scaled_sizes.end(), n) !=
           r_.info.scaled_sizes.end();
  }
  const std::vector<std::size_t>& sizes() const { return sizes_; }
  const std::vector<std::size_t>& study_sizes() const { return r_.info.study_sizes; }

  // A table: one line per structure, one column per size.
  std::string table(const std::string& test, const std::string& placement, double scale = 1) const {
    std::string out = "| structure |";
    std::string rule = "|---|";
    for (std::size_t n : sizes_) {
      out += " " + size_label(n) + (is_scaled(n) ? "*" : "") + " |";
      rule += "---:|";
    }
    out += "\n" + rule + "\n";
    for (std::size_t i = 0; i < r_.info.structures.size(); ++i) {
      const std::string& s = r_.info.structures[i];
      if (!measures(s, test)) continue;
      out += "| " + s + (r_.info.peers[i] ? " (peer)" : "") + " |";
      for (std::size_t n : sizes_) {
        const auto v = get(s, test, placement, n);
        std::string cell = v ? number(*v * scale) : (skipped(s, n) ? "skip" : "–");
        if (wrong(s, n)) cell += " " + red("✗");
        out += " " + cell + " |";
      }
      out += "\n";
    }
    return out;
  }

 private:
  const PaperResults& r_;
  std::map<std::tuple<std::string, std::string, std::string, std::size_t>, const Row*> rows_;
  std::set<std::pair<std::string, std::size_t>> skipped_, wrong_;
  std::map<std::string, std::set<std::string>> tests_;  // the tests each structure has rows of
  std::vector<std::size_t> sizes_;
};

struct Verdict {
  std::string verdict;
  std::string detail;
};

std::string verdict_of(std::size_t holds, std::size_t total) {
  if (total == 0) return "Cannot check";
  if (holds == total) return "Reproduced";
  if (2 * holds >= total) return "Partly reproduced";
  return "Not reproduced";
}

std::string missing_note(const Index& ix, const RunInfo& info,
                         std::initializer_list<const char*> needed) {
  std::string out;
  for (const char* s : needed) {
    if (ix.has(s)) continue;
    const bool registered =
        std::find(info.registered.begin(), info.registered.end(), s) != info.registered.end();
    out += (out.empty() ? "" : "; ") + std::string("`") + s + "` is " +
           (registered ? "not selected in this run (--algos)" : "not registered in this build");
  }
  return out;
}

// (a) the hgrid performs the fewest narrow-phase tests at every N.
Verdict finding_a(const Index& ix, const RunInfo& info) {
  if (!ix.has(kHgrid) || (!ix.has(kOctree) && !ix.has(kNaive)))
    return {"Cannot check", missing_note(ix, info, {kHgrid, kOctree, kNaive})};
  std::size_t holds = 0, total = 0;
  std::string fails;
  for (const char* pl : {"uneven", "even"}) {
    for (std::size_t n : ix.study_sizes()) {
      const auto h = ix.get(kHgrid, "query_tests", pl, n);
      if (!h) continue;
      double best_other = INFINITY;
      std::string other;
      for (const char* s : {kOctree, kNaive}) {
        const auto v = ix.get(s, "query_tests", pl, n);
        if (v && *v < best_other) best_other = *v, other = s;
      }
      if (!std::isfinite(best_other)) continue;
      ++total;
      if (*h <= best_other)
        ++holds;
      else
        fails += " " + std::string(pl) + " N=" + std::to_string(n) + " (" + number(*h) + " vs " +
                 other + " " + number(best_other) + ");";
    }
  }
  std::string detail = "hgrid-paper had the fewest tests per query in " + std::to_string(holds) +
                       " of " + std::to_string(total) + " (placement, N) cases of Tests 3 and 4.";
  const std::size_t last = ix.study_sizes().empty() ? 0 : ix.study_sizes().back();
  const auto h = ix.get(kHgrid, "query_tests", "even", last),
             o = ix.get(kOctree, "query_tests", "even", last),
             nv = ix.get(kNaive, "query_tests", "even", last);
  if (h) {
    detail += " At N=" + std::to_string(last) + " (even): hgrid " + number(*h);
    if (o) detail += ", octree " + number(*o);
    if (nv) detail += ", naive " + number(*nv);
    detail += " tests per query.";
  }
  if (!fails.empty()) detail += " Exceptions:" + fails;
  const std::string miss = missing_note(ix, info, {kOctree, kNaive});
  if (!miss.empty()) detail += " (" + miss + ".)";
  return {verdict_of(holds, total), detail};
}

// (b) the octree beats the hgrid below a few hundred objects and loses above.
Verdict finding_b(const Index& ix, const RunInfo& info) {
  if (!ix.has(kOctree) || !ix.has(kHgrid))
    return {"Cannot check", missing_note(ix, info, {kOctree, kHgrid})};
  std::size_t holds = 0, total = 0;
  std::string detail =
      "Query time (Tests 1 and 2), octree-paper / hgrid-paper (below 1: the octree is faster).";
  for (const char* pl : {"uneven", "even"}) {
    std::string list;
    std::vector<std::pair<std::size_t, double>> r;
    for (std::size_t n : ix.study_sizes()) {
      const auto o = ix.get(kOctree, "query_time", pl, n), h = ix.get(kHgrid, "query_time", pl, n);
      if (!o || !h || *h <= 0) continue;
      r.push_back({n, *o / *h});
      list += (list.empty() ? "" : ", ") + std::to_string(n) + ": " + number(*o / *h);
    }
    if (r.empty()) continue;
    // The study's shape: the octree faster up to some N* of a few hundred
    // (100 < N* <= 1600), the hgrid faster from there on.
    std::size_t first_hgrid = 0;
    bool monotone = true;
    for (const auto& [n, q] : r) {
      if (q > 1 && first_hgrid == 0) first_hgrid = n;
      if (first_hgrid != 0 && q <= 1) monotone = false;
    }
    ++total;
    const bool ok = monotone && first_hgrid > 100 && first_hgrid <= 1600 && r.front().second <= 1;
    if (ok) ++holds;
    detail += " " + std::string(pl) + ": " + list + " → ";
    if (first_hgrid == 0)
      detail += "the octree is faster at every N.";
    else if (r.front().second > 1)
      detail += "the hgrid is faster from the smallest N on.";
    else
      detail += "the hgrid is faster from N=" + std::to_string(first_hgrid) +
                (monotone ? "" : " (not at every larger N)") + ".";
  }
  return {verdict_of(holds, total), detail};
}

// (c) naive has the fastest insertion and the hgrid the slowest.
Verdict finding_c(const Index& ix, const RunInfo& info) {
  if (!ix.has(kNaive) || !ix.has(kHgrid) || !ix.has(kOctree))
    return {"Cannot check", missing_note(ix, info, {kNaive, kOctree, kHgrid})};
  std::size_t holds = 0, total = 0;
  std::string list;
  for (std::size_t n : ix.study_sizes()) {
    const auto a = ix.get(kNaive, "insert_time", "even", n),
               o = ix.get(kOctree, "insert_time", "even", n),
               h = ix.get(kHgrid, "insert_time", "even", n);
    if (!a || !o || !h) continue;
    ++total;
    if (*a <= *o && *a <= *h && *h >= *o) ++holds;
    list += (list.empty() ? "" : "; ") + std::to_string(n) + ": " + number(*a) + " / " +
            number(*o) + " / " + number(*h);
  }
  return {verdict_of(holds, total), "Test 5, ns per insertion, naive / octree / hgrid: " + list +
                                        ". Naive fastest and hgrid slowest at " +
                                        std::to_string(holds) + " of " + std::to_string(total) +
                                        " sizes."};
}

// (d) hgrid removal is many times faster than octree and naive removal.
Verdict finding_d(const Index& ix, const RunInfo& info) {
  if (!ix.has(kHgrid) || (!ix.has(kOctree) && !ix.has(kNaive)))
    return {"Cannot check", missing_note(ix, info, {kHgrid, kOctree, kNaive})};
  constexpr double kMany = 2;
  std::size_t holds = 0, total = 0;
  std::string list;
  for (std::size_t n : ix.study_sizes()) {
    const auto h = ix.get(kHgrid, "remove_time", "even", n);
    if (!h || *h <= 0) continue;
    const auto o = ix.get(kOctree, "remove_time", "even", n),
               a = ix.get(kNaive, "remove_time", "even", n);
    if (!o && !a) continue;
    ++total;
    bool ok = true;
    std::string item = std::to_string(n) + ":";
    if (o) ok = ok && *o / *h >= kMany, item += " octree " + ratio(*o / *h);
    if (a) ok = ok && *a / *h >= kMany, item += " naive " + ratio(*a / *h);
    if (ok) ++holds;
    list += (list.empty() ? "" : "; ") + item;
  }
  std::string detail =
      "Test 6, removal time relative to hgrid-paper's (\"many times\" taken as at least 2×): " +
      list + ".";
  const std::string miss = missing_note(ix, info, {kOctree, kNaive});
  if (!miss.empty()) detail += " (" + miss + ".)";
  return {verdict_of(holds, total), detail};
}

// (e) the octree does more tests with even placement than uneven.
Verdict finding_e(const Index& ix, const RunInfo& info) {
  if (!ix.has(kOctree)) return {"Cannot check", missing_note(ix, info, {kOctree})};
  std::size_t holds = 0, total = 0;
  std::string list;
  for (std::size_t n : ix.study_sizes()) {
    const auto e = ix.get(kOctree, "query_tests", "even", n),
               u = ix.get(kOctree, "query_tests", "uneven", n);
    if (!e || !u) continue;
    ++total;
    if (*e > *u) ++holds;
    list +=
        (list.empty() ? "" : "; ") + std::to_string(n) + ": " + number(*e) + " vs " + number(*u);
  }
  return {verdict_of(holds, total),
          "octree-paper tests per query, even vs uneven (Test 4 vs Test 3): " + list +
              ". More with even placement at " + std::to_string(holds) + " of " +
              std::to_string(total) + " sizes."};
}

}  // namespace

double study_memory_formula(const std::string& structure, std::size_t n) {
  const double x = static_cast<double>(n);
  if (structure == kNaive) return 4 + 4 * x;
  if (structure == kOctree) return 44460 + 4 * x;
  if (structure == kHgrid) return 37452 + 12 * x;
  return -1;
}

void fill_provenance(RunInfo& info) {
  info.cpu = field_of("/proc/cpuinfo", "model name");
  if (info.cpu.empty()) info.cpu = "unknown CPU";
  info.cores = std::thread::hardware_concurrency();
  const std::string mem = field_of("/proc/meminfo", "MemTotal");
  info.memory_gib = mem.empty() ? 0 : std::strtod(mem.c_str(), nullptr) / (1024.0 * 1024.0);
  info.compiler = BROADPHASE_COMPILER;
  info.flags = trim(BROADPHASE_CXX_FLAGS);
  info.build_type = BROADPHASE_BUILD_TYPE;
  const std::string src = BROADPHASE_SOURCE_DIR;
  info.commit = shell_line("git -C '" + src + "' rev-parse HEAD 2>/dev/null");
  if (info.commit.empty()) {
    info.commit = "unknown (no git repository at " + src + ")";
  } else if (!shell_line("git -C '" + src + "' status --porcelain --untracked-files=no 2>/dev/null")
                  .empty()) {
    info.commit += " (with uncommitted changes)";
  }
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) std::snprintf(host, sizeof host, "unknown-host");
  info.host = host;
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char date[64];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", &tm);
  info.date = date;
  info.command = command_line();
}

void write_csv(const std::filesystem::path& path, const std::vector<Row>& rows) {
  OutputFile file(path);  // whole or absent, and a failed write says why
  std::ostream& out = file.stream();
  out << "structure,peer,test,study_test,placement,dist,n,world,unit,median,min,max,q1,q3,reps,"
         "note\n";
  char buf[64];
  auto num = [&buf](double v) {
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return std::string(buf);
  };
  for (const Row& r : rows) {
    out << csv_field(r.structure) << ',' << (r.peer ? 1 : 0) << ',' << r.test << ',' << r.study_test
        << ',' << r.placement << ',' << r.dist << ',' << r.n << ',' << num(r.world) << ',' << r.unit
        << ',' << num(r.stat.median) << ',' << num(r.stat.min) << ',' << num(r.stat.max) << ','
        << num(r.stat.q1) << ',' << num(r.stat.q3) << ',' << r.stat.reps << ',' << csv_field(r.note)
        << '\n';
  }
  file.commit();
}

nlohmann::ordered_json row_json(const Row& r) {
  return {{"structure", r.structure},
          {"peer", r.peer},
          {"test", r.test},
          {"study_test", r.study_test},
          {"placement", r.placement},
          {"dist", r.dist},
          {"n", r.n},
          {"world", r.world},
          {"unit", r.unit},
          {"median", r.stat.median},
          {"min", r.stat.min},
          {"max", r.stat.max},
          {"q1", r.stat.q1},
          {"q3", r.stat.q3},
          {"reps", r.stat.reps},
          {"note", r.note}};
}

void write_json(const std::filesystem::path& path, const PaperResults& res) {
  using json = nlohmann::ordered_json;
  const RunInfo& i = res.info;
  json j;
  j["run"] = {{"date", i.date},
              {"command", i.command},
              {"commit", i.commit},
              {"host", i.host},
              {"cpu", i.cpu},
              {"cores", i.cores},
              {"memory_gib", i.memory_gib},
              {"compiler", i.compiler},
              {"flags", i.flags},
              {"build_type", i.build_type},
              {"quick", i.quick},
              {"seed", i.seed},
              {"budget_seconds", i.budget_seconds},
              {"study_budget_seconds", i.study_budget_seconds},
              {"cell_cap_seconds", i.cell_cap_seconds},
              {"elapsed_seconds", i.elapsed_seconds},
              {"study_seconds", i.study_seconds},
              {"study_sizes", i.study_sizes},
              {"scaled_sizes", i.scaled_sizes},
              {"reps", i.reps_rule},
              {"min_rep_seconds", i.min_rep_seconds},
              {"structures", i.structures},
              {"plots", i.plots},
              {"budget_notes", i.budget_notes},
              {"time_scale", i.time_scale}};
  json rows = json::array();
  for (const Row& r : res.rows) {
    rows.push_back(row_json(r));
  }
  j["rows"] = std::move(rows);
  json skips = json::array();
  for (const Skip& s : res.skips)
    skips.push_back({{"structure", s.structure},
                     {"n", s.n},
                     {"projected_seconds", s.projected_seconds},
                     {"cap_seconds", s.cap_seconds},
                     {"reason", s.reason}});
  j["skipped"] = std::move(skips);
  json scenes = json::array();
  for (const SceneSummary& s : res.scenes) {
    json frames = json::array();
    for (const FrameDigest& d : s.frames)
      frames.push_back({{"pairs", d.pairs}, {"hash", hex16(d.hash)}});
    scenes.push_back({{"n", s.n},
                      {"placement", s.placement},
                      {"dist", s.dist},
                      {"world", s.world},
                      {"moving", s.moving},
                      {"seed", s.seed},
                      {"structures", s.structures},
                      {"frames", std::move(frames)}});
  }
  j["scenes"] = std::move(scenes);
  json mism = json::array();
  for (const Mismatch& m : res.mismatches)
    mism.push_back({{"n", m.n},
                    {"placement", m.placement},
                    {"what", m.what},
                    {"structure", m.structure},
                    {"got", m.got},
                    {"expected", m.expected},
                    {"reference", m.reference}});
  j["comparisons"] = res.comparisons;
  j["mismatches"] = std::move(mism);
  j["figures"] = res.figures;
  write_file_atomically(path, j.dump(1) + '\n');
}

std::string report_markdown(const PaperResults& res) {
  const RunInfo& info = res.info;
  const Index ix(res);
  std::ostringstream md;
  md << "# broadphase paper: the study's six tests, reproduced\n\n";
  if (!res.mismatches.empty()) {
    md << red("ERROR: " + std::to_string(res.mismatches.size()) +
              " result(s) disagree between structures; see \"Exactness\" below.")
       << "\n\n";
  }
  md << "## The run\n\n";
  md << "| | |\n|---|---|\n";
  md << "| date | " << info.date << " |\n";
  md << "| command | `" << info.command << "` |\n";
  md << "| commit | " << info.commit << " |\n";
  md << "| machine | " << info.host << ": " << info.cpu << ", " << info.cores << " cores, ";
  char mem[32];
  std::snprintf(mem, sizeof mem, "%.1f", info.memory_gib);
  md << mem << " GiB |\n";
  md << "| compiler | " << info.compiler << ", " << info.build_type << ", flags `" << info.flags
     << "` (plus -ffp-contract=off on the library) |\n";
  md << "| mode | "
     << (info.quick ? "--quick (small sizes, few repetitions: a smoke test, not a measurement)"
                    : "full")
     << ", seed " << info.seed << " |\n";
  md << "| repetitions | " << info.reps_rule << "; every timed loop runs at least "
     << number(info.min_rep_seconds * 1e3) << " ms |\n";
  md << "| budget | " << number(info.budget_seconds) << " s in all, "
     << number(info.study_budget_seconds) << " s for the six tests, at most "
     << number(info.cell_cap_seconds) << " s per structure and size |\n";
  md << "| time taken | " << number(info.elapsed_seconds) << " s (" << number(info.study_seconds)
     << " s for the six tests) |\n";
  md << "| budget kept | "
     << (info.budget_notes.empty()
             ? std::string("no step ran far enough over its plan to cut anything")
             : std::to_string(info.budget_notes.size()) +
                   " cuts or overruns, listed below the sizes")
     << " |\n";
  if (info.time_scale != 1)
    md << "| time scale | " << number(info.time_scale)
       << ": every second counted as that many (BROADPHASE_LAB_TIME_SCALE, a test's stand-in "
          "for a loaded machine) |\n";
  md << "| structures | " << info.structures.size() << ": ";
  for (std::size_t i = 0; i < info.structures.size(); ++i)
    md << (i ? ", " : "") << "`" << info.structures[i] << "`" << (info.peers[i] ? " (peer)" : "");
  md << " |\n\n";
  md << "Sizes: the study's N = ";
  for (std::size_t i = 0; i < info.study_sizes.size(); ++i)
    md << (i ? ", " : "") << info.study_sizes[i];
  if (!info.scaled_sizes.empty()) {
    md << "; scaled scenes (marked *, the study's density of 6400 objects per km³) at N = ";
    for (std::size_t i = 0; i < info.scaled_sizes.size(); ++i)
      md << (i ? ", " : "") << info.scaled_sizes[i];
  }
  md << ". Raw numbers with their spread (min, max, quartiles): `results.csv`, `results.json`.\n\n";
  if (!info.budget_notes.empty()) {
    md << "The run measured the time it spent as it went and fell behind its plan; what it "
          "cut, and why:\n\n";
    for (const std::string& note : info.budget_notes) md << "- " << note << "\n";
    md << "\n";
  }

  // Spread of the repeated measurements.
  std::vector<double> spread;
  const Row* worst = nullptr;
  double worst_spread = -1;
  for (const Row& r : res.rows) {
    if (r.stat.reps < 2 || r.stat.median <= 0 || r.unit == "tests") continue;
    const double s = (r.stat.q3 - r.stat.q1) / r.stat.median;
    spread.push_back(s);
    if (s > worst_spread) worst_spread = s, worst = &r;
  }
  if (!spread.empty()) {
    const Stat s = summarize(spread);
    md << "Noise: the interquartile range of the repeated timings is " << number(s.median * 100)
       << "% of the median in a typical cell, " << number(worst_spread * 100) << "% at worst ("
       << worst->structure << ", " << worst->test << ", " << worst->placement << ", N=" << worst->n
       << "). The machine is shared: read ratios, not absolute times.\n\n";
  }

  md << "## The study's findings, checked\n\n";
  md << "| finding | this run | numbers |\n|---|---|---|\n";
  const std::pair<const char*, Verdict> findings[] = {
      {"(a) the hgrid performs the fewest narrow-phase tests at every N", finding_a(ix, info)},
      {"(b) the octree beats the hgrid below a few hundred objects and loses above",
       finding_b(ix, info)},
      {"(c) naive has the fastest insertion, the hgrid the slowest", finding_c(ix, info)},
      {"(d) hgrid removal is many times faster than octree and naive removal", finding_d(ix, info)},
      {"(e) the octree does more tests with even placement than with uneven", finding_e(ix, info)}};
  for (const auto& [what, v] : findings)
    md << "| " << what << " | **" << v.verdict << "** | " << v.detail << " |\n";
  md << "\nOnly the study's sizes (50 to 6400) count for the verdicts; \"Partly\" means it holds "
        "at "
        "half the cases or more.\n\n";

  md << "## Exactness: pairs and query results agree\n\n";
  if (res.mismatches.empty()) {
    md << "Every structure reported the same pairs (count and hash) on every frame, and the same "
          "number of objects in every query pass: "
       << res.comparisons << " results compared on " << res.scenes.size() << " scenes.\n\n";
  } else {
    md << red("MISMATCH") << ": " << res.mismatches.size() << " of " << res.comparisons
       << " results disagree with the reference (naive's when it ran, else the majority).\n\n";
    md << "| N | placement | what | structure | got | expected | reference "
          "|\n|---:|---|---|---|---|---|---|\n";
    for (const Mismatch& m : res.mismatches)
      md << "| " << m.n << " | " << m.placement << " | " << m.what << " | " << red(m.structure)
         << " | " << m.got << " | " << m.expected << " | " << m.reference << " |\n";
    md << "\n";
  }

  md << "## How the tests were run\n\n"
        "Each structure gets a fresh instance per scene (Config::world = the scene's cube, "
        "expected_objects = N), filled through `Replay` (moving objects as Motion::dynamic, the "
        "others as Motion::fixed). Then, for each repetition: one frame (the moving 20% move, the "
        "structure updates them in bulk, all pairs are reported; its time is the frame time), and "
        "one overlap query per moving object with its own sphere at its new position (Tests 1-4: "
        "the time per query, and QueryCost::tests per query). "
        "Tests 5 and 6 (even placement only, as in the study): a batch of k = N/10 objects (at "
        "least 4, at most 1024), chosen at random, is removed (timed: Test 6) and the same objects "
        "inserted again (timed: Test 5), so the structure holds between N − k and N objects; "
        "batches repeat until the timed part exceeds the minimum loop time. Query passes and "
        "batches are timed one by one and a repetition reports the median one, so that a "
        "preempted pass does not count for the others. Times are per object, the clock's own "
        "overhead subtracted. See docs/lab.md.\n\n";

  auto section = [&](const std::string& title, const std::string& what, const std::string& test,
                     const std::string& placement, double scale = 1) {
    md << "### " << title << "\n\n"
       << (what.empty() ? "" : what + "\n\n") << ix.table(test, placement, scale) << "\n";
  };
  md << "## Tests 1 and 2: time of one overlap query\n\n";
  section("Test 1: uneven placement", "Median ns per query of a moving object.", "query_time",
          "uneven");
  section("Test 2: even placement", "Median ns per query of a moving object.", "query_time",
          "even");
  md << "## Tests 3 and 4: narrow-phase tests per query\n\n";
  section("Test 3: uneven placement",
          "Median exact predicate evaluations per query (QueryCost::tests).", "query_tests",
          "uneven");
  section("Test 4: even placement",
          "Median exact predicate evaluations per query (QueryCost::tests).", "query_tests",
          "even");
  md << "## Tests 5 and 6: insertion and removal\n\n";
  section("Test 5: insertion into a structure holding N (even)", "Median ns per inserted object.",
          "insert_time", "even");
  section("Test 6: removal from a structure holding N (even)", "Median ns per removed object.",
          "remove_time", "even");

  md << "## Memory\n\n";
  md << "Bytes per object held by each structure (memory_bytes() / N, even placement, capacities "
        "included).\n\n";
  {
    std::string t = "| structure |", rule = "|---|";
    for (std::size_t n : ix.sizes())
      t += " " + size_label(n) + (ix.is_scaled(n) ? "*" : "") + " |", rule += "---:|";
    md << t << "\n" << rule << "\n";
    for (std::size_t i = 0; i < info.structures.size(); ++i) {
      const std::string& s = info.structures[i];
      md << "| " << s << (info.peers[i] ? " (peer)" : "") << " |";
      for (std::size_t n : ix.sizes()) {
        const auto v = ix.get(s, "memory", "even", n);
        md << " " << (v ? number(*v / static_cast<double>(n)) : (ix.skipped(s, n) ? "skip" : "–"))
           << " |";
      }
      md << "\n";
      // The lean path reads the caller's arrays in place: its own bytes
      // above, and here with those arrays, to set beside the structures
      // that hold their own copy of every shape.
      if (!ix.has_rows(s, "memory_with_arrays")) continue;
      md << "| " << s << " with the caller's arrays |";
      for (std::size_t n : ix.sizes()) {
        const auto v = ix.get(s, "memory_with_arrays", "even", n);
        md << " " << (v ? number(*v / static_cast<double>(n)) : (ix.skipped(s, n) ? "skip" : "–"))
           << " |";
      }
      md << "\n";
    }
  }
  if (ix.has(kArraysSeries))
    md << "\n`" << kArraysSeries
       << "` is the lean path (include/broadphase/arrays/arrays.hpp: a PairTracker over the "
          "caller's "
          "arrays): its own line counts only what the tracker keeps between calls; the line "
          "with the caller's arrays adds the columns it reads in place (centres and radii, 32 "
          "bytes per sphere), which the other structures hold a copy of.\n";
  md << "\nBeside the study's formulas (bytes on its 32-bit machine: naive 4 + 4n, octree 44 460 + "
        "4n, hgrid 37 452 + 12n). Ours store double-precision shapes, handles and user data, so "
        "they hold more per object; the constant term shows what a structure allocates up "
        "front.\n\n";
  {
    md << "| N |";
    std::string rule = "|---:|";
    for (const char* s : {kNaive, kOctree, kHgrid}) {
      md << " " << s << " (bytes) | study formula |";
      rule += "---:|---:|";
    }
    md << "\n" << rule << "\n";
    for (std::size_t n : ix.sizes()) {
      md << "| " << size_label(n) << (ix.is_scaled(n) ? "*" : "") << " |";
      for (const char* s : {kNaive, kOctree, kHgrid}) {
        const auto v = ix.get(s, "memory", "even", n);
        md << " "
           << (v ? number(*v) : (ix.has(s) ? (ix.skipped(s, n) ? "skip" : "–") : "not in run"))
           << " | " << number(study_memory_formula(s, n)) << " |";
      }
      md << "\n";
    }
    md << "\n";
  }

  md << "## Beyond the study: the frame an engine runs\n\n";
  md << "Median time of one frame (move the moving 20%, bulk update, report every pair), in "
        "ms.";
  if (ix.has(kArraysSeries))
    md << " `" << kArraysSeries
       << "`: the lean path, one PairTracker call per frame over the caller's arrays, told "
          "which objects moved (Changes::only), the same motion and pairs.";
  md << "\n\n";
  section("Frame time, even placement", "", "frame_time", "even");
  section("Frame time, uneven placement", "", "frame_time", "uneven");
  md << "Pairs per frame (the same for every structure):\n\n| N |";
  for (std::size_t n : ix.sizes())
    md << " " << size_label(n) << (ix.is_scaled(n) ? "*" : "") << " |";
  md << "\n|---|";
  for (std::size_t k = 0; k < ix.sizes().size(); ++k) md << "---:|";
  for (const char* pl : {"even", "uneven"}) {
    md << "\n| " << pl << " |";
    for (std::size_t n : ix.sizes()) {
      std::string cell = "–";
      for (const SceneSummary& s : res.scenes) {
        if (s.n != n || s.placement != pl || s.frames.empty()) continue;
        double sum = 0;
        for (const FrameDigest& d : s.frames) sum += static_cast<double>(d.pairs);
        cell = number(sum / static_cast<double>(s.frames.size()));
      }
      md << " " << cell << " |";
    }
  }
  md << "\n\n";

  md << "### Versus peers\n\n";
  bool any_peer = false;
  for (bool p : info.peers) any_peer = any_peer || p;
  if (!any_peer) {
    md << "No peer library is in this run (none was built, or --no-peers / --algos left them out), "
          "so there is nothing to compare against.\n\n";
  } else {
    md << "Frame time (even placement) divided by the fastest peer's at the same N (below 1: "
          "faster than every peer). The peer named in the header row is the fastest one.\n\n";
    md << "| structure |";
    std::string rule = "|---|";
    std::map<std::size_t, std::pair<double, std::string>> best;
    for (std::size_t n : ix.sizes()) {
      for (std::size_t i = 0; i < info.structures.size(); ++i) {
        if (!info.peers[i]) continue;
        const auto v = ix.get(info.structures[i], "frame_time", "even", n);
        if (v && (best.count(n) == 0 || *v < best[n].first)) best[n] = {*v, info.structures[i]};
      }
      md << " " << size_label(n) << (ix.is_scaled(n) ? "*" : "")
         << (best.count(n) ? " (" + best[n].second + ")" : "") << " |";
      rule += "---:|";
    }
    md << "\n" << rule << "\n";
    for (std::size_t i = 0; i < info.structures.size(); ++i) {
      const std::string& s = info.structures[i];
      md << "| " << s << (info.peers[i] ? " (peer)" : "") << " |";
      for (std::size_t n : ix.sizes()) {
        const auto v = ix.get(s, "frame_time", "even", n);
        const bool ok = v && best.count(n) && best[n].first > 0;
        md << " " << (ok ? number(*v / best[n].first) : (ix.skipped(s, n) ? "skip" : "–")) << " |";
      }
      md << "\n";
    }
    md << "\n";
  }

  md << "## Skipped\n\n";
  if (res.skips.empty()) {
    md << "Nothing was skipped: every structure ran at every size.\n\n";
  } else {
    md << "A structure is skipped at a size when its projected time there (each part of the "
          "measurement extrapolated from the two previous sizes by its observed growth) exceeds "
          "the cap per structure and size, or what is left of the budget; once skipped, it stays "
          "skipped at the larger sizes.\n\n";
    md << "| structure | skipped at N | why (at the first skipped size) |\n|---|---|---|\n";
    for (const std::string& s : info.structures) {
      std::string sizes, why;
      for (const Skip& k : res.skips) {
        if (k.structure != s) continue;
        sizes += (sizes.empty() ? "" : ", ") + size_label(k.n);
        if (why.empty()) why = k.reason;
      }
      if (!sizes.empty()) md << "| " << s << " | " << sizes << " | " << why << " |\n";
    }
    md << "\n";
  }

  md << "## Figures\n\n";
  if (!info.plots) {
    md << "Plots were skipped: " << info.plots_note
       << ". The CSV and JSON files hold every number; "
          "run `python3 tools/plot_paper.py --csv results.csv --out .` where matplotlib is "
          "installed.\n\n";
  } else {
    md << "Each figure exists as PNG and SVG. Figures 3.1 to 3.10 follow the study's order (see "
          "docs/lab.md); one line per structure, the study's three drawn thicker.\n\n";
    for (const std::string& f : res.figures) md << "![" << f << "](" << f << ")\n\n";
  }

  for (const std::string& s : res.sections)
    md << s << (s.empty() || s.back() == '\n' ? "" : "\n") << "\n";
  return md.str();
}

}  // namespace broadphase::app
