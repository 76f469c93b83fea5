// The steps of one `broadphase paper` run and their record in the output
// directory, so that an interrupted run says what it did and can be
// finished with `paper --resume DIR` without redoing the steps done.
//
// In DIR:
//   paper-state.json  the run's options and the steps done, rewritten
//                     (atomically) after each step;
//   RUN-INCOMPLETE    present from the start until every step is done: the
//                     steps done, those left, and the command to resume;
//   .paper-steps/     each done step's results for the report (the study's
//                     tables, each experiment's section), and the staging
//                     directory of the step under way.
// A step writes its files into its staging directory; they are moved into
// DIR only once the step is done, so an interrupted step leaves nothing in
// DIR that looks whole.
#pragma once

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "lab.hpp"
#include "paper_report.hpp"

namespace broadphase::app {

class PaperSteps {
 public:
  /// Starts a run in `dir` (created if needed): checks that files can be
  /// written there (a probe file; the reason on failure), then records the
  /// options and marks the run incomplete. A state left by an earlier run
  /// in `dir` is replaced. Throws std::runtime_error.
  static PaperSteps start(const std::filesystem::path& dir, const nlohmann::json& options);
  /// Reads the options of the run recorded in `dir`, for --resume. Throws
  /// std::runtime_error when `dir` holds no run's state.
  static nlohmann::json recorded_options(const std::filesystem::path& dir);
  /// Continues the run recorded in `dir`: the steps done are kept.
  static PaperSteps resume(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  bool done(const std::string& step) const { return done_.count(step) != 0; }
  bool complete() const { return complete_; }

  /// The study: when done before, fills the study's part of `res` (rows,
  /// skips, mismatches, scenes, comparisons, study seconds, the budget
  /// notes made so far) and returns true; results.csv is in DIR already.
  bool load_study(PaperResults& res) const;
  /// Records the study as done, with what load_study() gives back.
  void save_study(const PaperResults& res);

  /// Runs one experiment as a step, or returns its section when done
  /// before. `ctx.out_dir` is replaced by the step's staging directory,
  /// whose files move into DIR when the experiment returns. An exception
  /// leaves the step not done and is rethrown.
  std::string experiment(const std::string& name, LabContext ctx, const LabExperiment& run);

  /// Runs the plotting step into a staging directory (its figures move into
  /// DIR at the end), or returns the recorded result when done before.
  bool plots(const std::function<bool(const std::filesystem::path& into)>& run);

  /// Called once REPORT.md is written: with every step done the run is
  /// complete and RUN-INCOMPLETE is removed; otherwise it lists what is
  /// left (a failed experiment) and stays.
  void finish(const std::vector<std::string>& all_steps);

  /// The command that resumes this run.
  std::string resume_command() const;

 private:
  explicit PaperSteps(std::filesystem::path dir) : dir_(std::move(dir)) {}
  std::filesystem::path steps_dir() const { return dir_ / ".paper-steps"; }
  std::filesystem::path staging(const std::string& step) const;
  void mark_done(const std::string& step);
  void save() const;
  void move_into_place(const std::filesystem::path& from) const;
  static std::string file_name(const std::string& step);

  std::filesystem::path dir_;
  nlohmann::json options_;
  std::set<std::string> done_;
  std::vector<std::string> order_;  // steps in the order done
  bool complete_ = false;
};

}  // namespace broadphase::app
