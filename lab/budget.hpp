// The time `broadphase paper` spends, measured as it goes against its
// budget: the lab's clock, what each step planned and took, and the time
// left estimated from the rates measured so far rather than from the plan
// alone. The cuts made when the run falls behind are the driver's
// (paper.cpp), recorded in RunInfo::budget_notes.
#pragma once

#include <chrono>
#include <map>
#include <string>

namespace broadphase::app {

/// The lab's time scale: $BROADPHASE_LAB_TIME_SCALE, a number in [1, 1000]
/// (1 when unset or not such a number). Every second the run spends counts
/// as that many, against its budget and in its progress line, as on a
/// machine that many times slower or busier than the measurements say: the
/// tests' stand-in for a loaded machine. The measurements (the rows of
/// results.csv, the costs the study projects from) are never scaled.
double lab_time_scale();

/// Seconds on the lab's clock since `t0`: wall seconds times lab_time_scale().
double lab_seconds_since(std::chrono::steady_clock::time_point t0);

/// One run's budget: the steps planned and taken.
class RunBudget {
 public:
  /// `total`: seconds the run may take; `tail`: what is planned for the
  /// steps after the last one begun with a plan of its own (figures, report).
  RunBudget(double total, double tail);

  double total() const { return total_; }
  /// Lab seconds since the run started.
  double spent() const { return lab_seconds_since(start_); }
  /// What is left of the budget (negative once it is spent).
  double left() const { return total_ - spent(); }
  double tail() const { return tail_; }

  /// Starts the step `name`, planned to take `planned` lab seconds; steps
  /// of one `kind` (the experiments) share a pace of their own.
  void begin(const std::string& name, double planned, const std::string& kind = "");
  /// Ends the step begun last; returns the lab seconds it took.
  double end();
  const std::string& step() const { return step_; }
  double step_planned() const { return planned_; }
  double step_spent() const { return lab_seconds_since(step_start_); }

  /// How much slower than planned the steps ended so far ran (their lab
  /// seconds over their plans), those of `kind` alone once one of them has
  /// ended, or `observed` when that is more: at least 1.
  double pace(double observed = 1, const std::string& kind = "") const;

  /// The current step's seconds left from the fraction of it done: its
  /// plan, slowed by pace(), less what it has spent; or what the rate so
  /// far gives (spent × (1 - f) / f) when that is more; and a step past
  /// its plan with no fraction to go by is given a quarter of what it has
  /// spent again, never zero while it runs.
  double step_left(double fraction, double observed = 1) const;

  /// The seconds left in all: `step_left` (the current step's, from
  /// step_left() or the caller's own projection), plus the `planned_after`
  /// seconds of the steps of `kind` still to begin, slowed by their pace,
  /// and the tail, slowed by the larger of that and the run's pace.
  double estimate_left(double step_left, double planned_after, double observed = 1,
                       const std::string& kind = "") const;

 private:
  double total_, tail_;
  std::chrono::steady_clock::time_point start_, step_start_;
  std::string step_, kind_;
  double planned_ = 0;
  // The steps ended: planned and spent, in all and by kind.
  struct Sums {
    double planned = 0, spent = 0;
  };
  Sums done_;
  std::map<std::string, Sums> by_kind_;
};

/// How far over `plan` a ratio of actual to planned is: "40% over the
/// plan" for 1.4, "2.5 times the plan" from 2 up.
std::string over_text(double ratio, const std::string& plan);

}  // namespace broadphase::app
