#include "budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace broadphase::app {

double lab_time_scale() {
  static const double scale = [] {
    const char* text = std::getenv("BROADPHASE_LAB_TIME_SCALE");
    if (text == nullptr || *text == '\0') return 1.0;
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    return *end == '\0' && v >= 1 && v <= 1000 ? v : 1.0;
  }();
  return scale;
}

double lab_seconds_since(std::chrono::steady_clock::time_point t0) {
  return lab_time_scale() *
         std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

RunBudget::RunBudget(double total, double tail)
    : total_(total), tail_(tail), start_(std::chrono::steady_clock::now()), step_start_(start_) {}

void RunBudget::begin(const std::string& name, double planned, const std::string& kind) {
  step_ = name;
  kind_ = kind;
  planned_ = std::max(0.0, planned);
  step_start_ = std::chrono::steady_clock::now();
}

double RunBudget::end() {
  const double took = step_spent();
  for (Sums* sums : {&done_, &by_kind_[kind_]}) {
    sums->planned += planned_;
    sums->spent += took;
  }
  step_.clear();
  kind_.clear();
  planned_ = 0;
  return took;
}

double RunBudget::pace(double observed, const std::string& kind) const {
  const auto it = by_kind_.find(kind);
  const Sums& sums = !kind.empty() && it != by_kind_.end() ? it->second : done_;
  const double done = sums.planned > 0 ? sums.spent / sums.planned : 1;
  return std::max({1.0, done, observed});
}

double RunBudget::step_left(double fraction, double observed) const {
  const double spent = step_spent();
  double left = std::max(0.0, planned_ * pace(observed, kind_) - spent);
  if (fraction > 0.02 && fraction < 1) left = std::max(left, spent * (1 - fraction) / fraction);
  if (fraction <= 0.02 && spent > planned_) left = std::max(left, 0.25 * spent);
  return left;
}

double RunBudget::estimate_left(double step_left, double planned_after, double observed,
                                const std::string& kind) const {
  const double of_kind = pace(observed, kind);
  return std::max(0.0, step_left) + std::max(0.0, planned_after) * of_kind +
         tail_ * std::max(of_kind, pace(observed));
}

std::string over_text(double ratio, const std::string& plan) {
  char buf[32];
  if (ratio >= 2) {
    std::snprintf(buf, sizeof buf, "%.1f times ", ratio);
  } else {
    std::snprintf(buf, sizeof buf, "%.0f%% over ", std::max(0.0, ratio - 1) * 100);
  }
  return buf + plan;
}

}  // namespace broadphase::app
