// The lab's experiments beyond the study's six tests, registered like
// structures: each file of lab/experiments/ registers its own with
//   const RegisterExperiment kRegistered{{"name", order, description, run}};
// so that adding an experiment adds one file and edits nothing else. They
// are compiled into the program itself (an object library linked straight
// into the executable), so no registration is dropped by the linker.
#pragma once

#include <string>
#include <vector>

#include "lab.hpp"

namespace broadphase::app {

/// One experiment: its section of REPORT.md comes from `run`.
struct ExperimentInfo {
  std::string name;         ///< shown in the progress line and on failure
  int order = 0;            ///< report order: lower first
  std::string description;  ///< one line, for docs/lab.md and --help readers
  LabExperiment run;
  /// Its share of the experiments' budget relative to the others' (1 each
  /// by default): what it took, over what they took, on the 2-core hosts
  /// with a generous budget.
  double weight = 1;
};

/// The experiments' weights added up.
double experiment_weights();

/// The registered experiments, in report order.
const std::vector<ExperimentInfo>& experiments();

/// Registers an experiment at static initialisation.
struct RegisterExperiment {
  explicit RegisterExperiment(ExperimentInfo info);
};

}  // namespace broadphase::app
