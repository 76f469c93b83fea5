// The lab's main job: the command `broadphase paper`, run step by step
// (lab/paper.cpp; docs/lab.md says what each step measures).
//
// One name in the code: "paper" is the run as a whole (this driver, its
// options, its steps, PaperSteps, PaperResults, the command users type).
// "The study" is never a second name for it: it is only the published study
// whose six tests the run repeats, its first measuring step (`run_study`,
// RunInfo's study_* fields, kept as they are in results.json).
#pragma once

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace broadphase::app {

/// The default budget of a full run, in seconds: 25 minutes. Quiet 2-core
/// hosts took 24-26 minutes with the floors of every step met; a budget
/// below that cuts repetitions and sizes, said in the report.
inline constexpr double kDefaultBudget = 1500;

/// What `broadphase paper` was asked for (its --help says each option).
struct PaperOptions {
  bool quick = false;
  std::string out;
  std::vector<std::string> algos;
  std::size_t max_n = 0;
  bool max_n_given = false;
  std::uint64_t seed = 1;
  double budget = 0;
  bool peers = true;
  std::string resume;  ///< --resume DIR: the other options come from DIR's state
};

/// --resume: replaces the options of `o` by those recorded in `j` (what
/// PaperSteps::recorded_options reads), the output directory by o.resume.
/// Throws std::runtime_error when the record is damaged.
void apply_recorded_options(PaperOptions& o, const nlohmann::json& j);

/// Runs the whole job: checks the options (UsageError), measures, writes
/// results.csv, results.json, the figures and REPORT.md into the output
/// directory. Throws std::runtime_error when structures disagree or an
/// experiment failed, after writing the report.
void run_paper(const PaperOptions& o);

}  // namespace broadphase::app
