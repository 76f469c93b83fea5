#include "paper_steps.hpp"

#include <broadphase/scenes/output_file.hpp>
#include <fstream>
#include <stdexcept>

namespace broadphase::app {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

constexpr const char* kStateFile = "paper-state.json";
constexpr const char* kIncompleteFile = "RUN-INCOMPLETE";
constexpr int kStateVersion = 1;

json read_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  try {
    return json::parse(in);
  } catch (const json::exception& e) {
    throw std::runtime_error(path.string() + ": not a state file of broadphase paper (" + e.what() +
                             ")");
  }
}

std::string quoted_path(const fs::path& p) {
  std::string s = p.string(), out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

std::string PaperSteps::file_name(const std::string& step) {
  std::string out;
  for (char c : step) out += (std::isalnum(static_cast<unsigned char>(c)) != 0) ? c : '-';
  return out;
}

fs::path PaperSteps::staging(const std::string& step) const {
  return steps_dir() / (file_name(step) + ".partial");
}

std::string PaperSteps::resume_command() const {
  return "broadphase paper --resume " + quoted_path(dir_);
}

PaperSteps PaperSteps::start(const fs::path& dir, const json& options) {
  check_writable_directory(dir);
  PaperSteps s(dir);
  s.options_ = options;
  std::error_code ec;
  fs::remove_all(s.steps_dir(), ec);  // an earlier run's steps are not this run's
  fs::create_directories(s.steps_dir(), ec);
  if (ec) throw std::runtime_error(s.steps_dir().string() + ": cannot create: " + ec.message());
  s.save();
  return s;
}

json PaperSteps::recorded_options(const fs::path& dir) {
  const fs::path state = dir / kStateFile;
  if (!fs::exists(state))
    throw std::runtime_error(dir.string() + ": no run of broadphase paper to resume here (no " +
                             kStateFile + ")");
  const json j = read_json(state);
  if (!j.is_object() || j.value("version", 0) != kStateVersion || !j.contains("options"))
    throw std::runtime_error(state.string() + ": not a state file of this broadphase paper");
  return j["options"];
}

PaperSteps PaperSteps::resume(const fs::path& dir) {
  check_writable_directory(dir);
  const json j = read_json(dir / kStateFile);
  PaperSteps s(dir);
  s.options_ = j.at("options");
  for (const auto& step : j.at("done")) {
    s.done_.insert(step.get<std::string>());
    s.order_.push_back(step.get<std::string>());
  }
  s.complete_ = j.value("complete", false);
  std::error_code ec;
  fs::create_directories(s.steps_dir(), ec);
  // What an interrupted step had begun to write is redone from scratch.
  for (const auto& entry : fs::directory_iterator(s.steps_dir(), ec))
    if (entry.path().extension() == ".partial") fs::remove_all(entry.path(), ec);
  return s;
}

void PaperSteps::save() const {
  json j;
  j["version"] = kStateVersion;
  j["options"] = options_;
  j["done"] = order_;
  j["complete"] = complete_;
  write_file_atomically(dir_ / kStateFile, j.dump(1) + "\n");
  if (complete_) {
    std::error_code ec;
    fs::remove(dir_ / kIncompleteFile, ec);
    return;
  }
  std::string text =
      "This run of broadphase paper has not finished: its results here are partial.\n"
      "Steps done:";
  if (order_.empty()) text += " none";
  for (const std::string& s : order_) text += "\n  " + s;
  text += "\nFinish it (the steps done are not redone) with:\n  " + resume_command() + "\n";
  write_file_atomically(dir_ / kIncompleteFile, text);
}

void PaperSteps::mark_done(const std::string& step) {
  if (done_.insert(step).second) order_.push_back(step);
  save();
}

void PaperSteps::move_into_place(const fs::path& from) const {
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(from)) {
    const fs::path to = dir_ / entry.path().filename();
    // A file is replaced by rename itself; a directory (scenes/) must go first.
    if (entry.is_directory() && fs::is_directory(to)) fs::remove_all(to, ec);
    fs::rename(entry.path(), to, ec);
    if (ec) throw std::runtime_error(to.string() + ": cannot move into place: " + ec.message());
  }
  fs::remove_all(from, ec);
}

namespace {

Row row_of(const json& j) {
  Row r;
  j.at("structure").get_to(r.structure);
  j.at("peer").get_to(r.peer);
  j.at("test").get_to(r.test);
  j.at("study_test").get_to(r.study_test);
  j.at("placement").get_to(r.placement);
  j.at("dist").get_to(r.dist);
  j.at("n").get_to(r.n);
  j.at("world").get_to(r.world);
  j.at("unit").get_to(r.unit);
  j.at("median").get_to(r.stat.median);
  j.at("min").get_to(r.stat.min);
  j.at("max").get_to(r.stat.max);
  j.at("q1").get_to(r.stat.q1);
  j.at("q3").get_to(r.stat.q3);
  j.at("reps").get_to(r.stat.reps);
  j.at("note").get_to(r.note);
  return r;
}

}  // namespace

void PaperSteps::save_study(const PaperResults& res) {
  json j;
  j["study_seconds"] = res.info.study_seconds;
  j["budget_notes"] = res.info.budget_notes;
  j["comparisons"] = res.comparisons;
  json& rows = j["rows"] = json::array();
  for (const Row& r : res.rows) rows.push_back(json(row_json(r)));
  json& skips = j["skips"] = json::array();
  for (const Skip& s : res.skips)
    skips.push_back({s.structure, s.n, s.projected_seconds, s.cap_seconds, s.reason});
  json& mism = j["mismatches"] = json::array();
  for (const Mismatch& m : res.mismatches)
    mism.push_back({m.n, m.placement, m.what, m.structure, m.got, m.expected, m.reference});
  json& scenes = j["scenes"] = json::array();
  for (const SceneSummary& s : res.scenes) {
    json frames = json::array();
    for (const FrameDigest& d : s.frames) frames.push_back({d.pairs, d.hash});
    scenes.push_back({s.n, s.placement, s.dist, s.world, s.moving, s.seed, s.structures, frames});
  }
  write_file_atomically(steps_dir() / "study.json", j.dump() + "\n");
  mark_done("study");
}

bool PaperSteps::load_study(PaperResults& res) const {
  if (!done("study")) return false;
  const json j = read_json(steps_dir() / "study.json");
  try {
    j.at("study_seconds").get_to(res.info.study_seconds);
    // Absent from the state of a run interrupted before budget notes existed.
    if (j.contains("budget_notes")) j.at("budget_notes").get_to(res.info.budget_notes);
    j.at("comparisons").get_to(res.comparisons);
    for (const json& r : j.at("rows")) res.rows.push_back(row_of(r));
    for (const json& s : j.at("skips"))
      res.skips.push_back({s[0].get<std::string>(), s[1].get<std::size_t>(), s[2].get<double>(),
                           s[3].get<double>(), s[4].get<std::string>()});
    for (const json& m : j.at("mismatches"))
      res.mismatches.push_back({m[0].get<std::size_t>(), m[1].get<std::string>(),
                                m[2].get<std::string>(), m[3].get<std::string>(),
                                m[4].get<std::string>(), m[5].get<std::string>(),
                                m[6].get<std::string>()});
    for (const json& s : j.at("scenes")) {
      SceneSummary sum;
      s[0].get_to(sum.n);
      s[1].get_to(sum.placement);
      s[2].get_to(sum.dist);
      s[3].get_to(sum.world);
      s[4].get_to(sum.moving);
      s[5].get_to(sum.seed);
      s[6].get_to(sum.structures);
      for (const json& d : s[7]) {
        FrameDigest fd;
        d[0].get_to(fd.pairs);
        d[1].get_to(fd.hash);
        sum.frames.push_back(fd);
      }
      res.scenes.push_back(std::move(sum));
    }
  } catch (const json::exception& e) {
    throw std::runtime_error((steps_dir() / "study.json").string() + ": damaged (" + e.what() +
                             "); start the run again without --resume");
  }
  return true;
}

std::string PaperSteps::experiment(const std::string& name, LabContext ctx,
                                   const LabExperiment& run) {
  const fs::path section = steps_dir() / (file_name(name) + ".md");
  if (done(name)) {
    std::ifstream in(section);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  const fs::path stage = staging(name);
  std::error_code ec;
  fs::remove_all(stage, ec);
  fs::create_directories(stage, ec);
  if (ec) throw std::runtime_error(stage.string() + ": cannot create: " + ec.message());
  ctx.out_dir = stage;
  const std::string md = run(ctx);
  move_into_place(stage);
  write_file_atomically(section, md);
  mark_done(name);
  return md;
}

bool PaperSteps::plots(const std::function<bool(const fs::path& into)>& run) {
  const fs::path result = steps_dir() / "plots.json";
  if (done("plots")) return read_json(result).value("plots", false);
  const fs::path stage = staging("plots");
  std::error_code ec;
  fs::remove_all(stage, ec);
  fs::create_directories(stage, ec);
  if (ec) throw std::runtime_error(stage.string() + ": cannot create: " + ec.message());
  const bool ok = run(stage);
  move_into_place(stage);
  write_file_atomically(result, json{{"plots", ok}}.dump() + "\n");
  mark_done("plots");
  return ok;
}

void PaperSteps::finish(const std::vector<std::string>& all_steps) {
  for (const std::string& s : all_steps)
    if (!done(s)) {
      save();
      return;
    }
  complete_ = true;
  save();
}

}  // namespace broadphase::app
