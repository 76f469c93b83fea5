#include "experiment.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

namespace broadphase::app {

namespace {

std::vector<ExperimentInfo>& table() {
  static std::vector<ExperimentInfo> t;  // built before main: no lock needed
  return t;
}

}  // namespace

const std::vector<ExperimentInfo>& experiments() { return table(); }

double experiment_weights() {
  double w = 0;
  for (const ExperimentInfo& e : table()) w += e.weight;
  return w;
}

RegisterExperiment::RegisterExperiment(ExperimentInfo info) {
  auto& t = table();
  if (std::any_of(t.begin(), t.end(), [&](const ExperimentInfo& e) { return e.name == info.name; }))
    throw std::logic_error("lab: experiment registered twice: " + info.name);
  const auto at =
      std::upper_bound(t.begin(), t.end(), info.order,
                       [](int order, const ExperimentInfo& e) { return order < e.order; });
  t.insert(at, std::move(info));
}

}  // namespace broadphase::app
