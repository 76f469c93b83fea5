// The lab as data: the metrics every row of results.csv names (defined once
// in lab/metrics.json, which the plotting scripts read too) and the
// performance goals with their reference figures (lab/goals.json). Both
// files are built into the program (lab_data.hpp.in).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace broadphase::app {

/// One metric of results.csv (lab/metrics.json).
struct Metric {
  std::string name;  ///< the `test` column
  std::string unit;  ///< the `unit` column
  std::string label;
  nlohmann::json study_test;  ///< placement -> the study's test number
  /// The study's test number of this metric in `placement`, 0 when none.
  int study_test_for(std::string_view placement) const;
};

/// The metric named `name`. Throws std::logic_error for a name that
/// lab/metrics.json does not list: a new metric is added there first.
const Metric& metric(std::string_view name);

/// lab/goals.json, parsed once.
const nlohmann::json& goals();

}  // namespace broadphase::app
