#include "lab_data.hpp"

#include <map>
#include <stdexcept>

#include "lab_data_embedded.hpp"

namespace broadphase::app {

int Metric::study_test_for(std::string_view placement) const {
  const auto it = study_test.find(std::string(placement));
  return it == study_test.end() ? 0 : it->get<int>();
}

const Metric& metric(std::string_view name) {
  static const std::map<std::string, Metric, std::less<>> metrics = [] {
    std::map<std::string, Metric, std::less<>> out;
    // Parsed into a variable: a range-for over a member of a temporary
    // would read the document after its end.
    const nlohmann::json doc = nlohmann::json::parse(embedded::kMetricsJson);
    for (const nlohmann::json& m : doc.at("metrics")) {
      const std::string name = m.at("name").get<std::string>();
      out[name] = Metric{name, m.at("unit").get<std::string>(), m.at("label").get<std::string>(),
                         m.at("study_test")};
    }
    return out;
  }();
  const auto it = metrics.find(name);
  if (it == metrics.end())
    throw std::logic_error("lab: metric '" + std::string(name) +
                           "' is not in lab/metrics.json (add it there first)");
  return it->second;
}

const nlohmann::json& goals() {
  static const nlohmann::json g = nlohmann::json::parse(embedded::kGoalsJson);
  return g;
}

}  // namespace broadphase::app
