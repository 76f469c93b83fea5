// The lab's shared vocabulary: where a run writes, how it reports progress,
// and the experiments that families of structures add to the report.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace broadphase::app {

/// What every lab experiment gets from `broadphase paper`.
struct LabContext {
  std::filesystem::path out_dir;  ///< results/<date>-<host>/ or --out
  bool quick = false;             ///< --quick: everything small, under a minute in all
  std::uint64_t seed = 1;
  /// Structures selected with --algos (all library structures when empty).
  std::vector<std::string> algos;
  /// Reports progress on stderr: what is running, fraction done in [0, 1].
  std::function<void(const std::string& what, double fraction)> progress;
  /// Seconds the experiment may take at most (it scales its sizes to fit).
  double budget_seconds = 60;
  /// --max-n: the most objects any of the experiment's worlds may hold.
  std::size_t max_n = std::numeric_limits<std::size_t>::max();
  /// A world size of the experiment, capped by --max-n.
  std::size_t capped(std::size_t n) const { return std::min(n, max_n); }
};

/// One experiment's contribution to REPORT.md: a Markdown section (with its
/// own heading, "## ..."), having written its CSV and figures into out_dir.
/// Figures are referenced relative to out_dir. An experiment that cannot
/// run says so in its section; it never throws for a missing optional tool.
using LabExperiment = std::function<std::string(const LabContext&)>;

/// The experiments beyond the study's six tests register themselves:
/// experiment.hpp.

/// The Python interpreter that has matplotlib: $BROADPHASE_PYTHON, else
/// /usr/bin/python3 (where Debian's python3-matplotlib lives), else the
/// python3 on PATH; empty when none of them can import matplotlib.
std::string plot_python();

/// Runs the matplotlib script `tools/<script>` with arguments; returns false
/// (and says why on stderr) when python3 or matplotlib is missing or the
/// script fails. Throws ChildInterrupted (interrupt.hpp) when the script was
/// ended by SIGINT or SIGTERM.
bool run_plot_script(const std::string& script, const std::vector<std::string>& args);

}  // namespace broadphase::app
