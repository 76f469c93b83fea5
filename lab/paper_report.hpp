// The lab's outputs: raw CSV and JSON, and REPORT.md with the tables, the
// study's findings checked against this run, and the run's provenance.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "paper_measure.hpp"

namespace broadphase::app {

/// A structure left out at a size, and why (never silently).
struct Skip {
  std::string structure;
  std::size_t n = 0;
  double projected_seconds = 0;  ///< 0 when not projected (skipped at a smaller size)
  double cap_seconds = 0;
  std::string reason;
};

/// A disagreement with the reference on a scene: wrong pairs, a wrong
/// query result, or a structure that threw.
struct Mismatch {
  std::size_t n = 0;
  std::string placement;
  std::string what;  ///< "frame 3", "query pass 2", "error"
  std::string structure;
  std::string got, expected;
  std::string reference;  ///< the structures that gave `expected`
};

/// One scene of the run, with its reference pairs per frame.
struct SceneSummary {
  std::size_t n = 0;
  std::string placement, dist;
  double world = 0;
  std::size_t moving = 0;
  std::uint64_t seed = 0;
  std::vector<FrameDigest> frames;  ///< the agreed digest of each frame
  std::size_t structures = 0;       ///< how many structures were compared on it
};

/// Where and how the run was made.
struct RunInfo {
  std::string command, date, commit, host;
  std::string cpu, compiler, flags, build_type;
  unsigned cores = 0;
  double memory_gib = 0;
  bool quick = false;
  std::uint64_t seed = 1;
  double budget_seconds = 0, study_budget_seconds = 0, cell_cap_seconds = 0;
  double elapsed_seconds = 0, study_seconds = 0;
  std::vector<std::size_t> study_sizes, scaled_sizes;
  std::string reps_rule;
  double min_rep_seconds = 0;
  std::vector<std::string> structures;
  std::vector<bool> peers;
  std::vector<std::string> registered;  ///< every name the registry knows
  bool plots = false;
  std::string plots_note;
  /// What the run cut when it fell behind its plan, and the steps that ran
  /// over it, each "budget: ..." (budget.hpp; REPORT.md lists them).
  std::vector<std::string> budget_notes;
  double time_scale = 1;  ///< the lab's time scale (budget.hpp), 1 on a real run
};

/// Everything REPORT.md is made from.
struct PaperResults {
  RunInfo info;
  std::vector<Row> rows;
  std::vector<Skip> skips;
  std::vector<Mismatch> mismatches;
  std::vector<SceneSummary> scenes;
  std::size_t comparisons = 0;        ///< frame and query results compared
  std::vector<std::string> sections;  ///< the other families' experiments
  std::vector<std::string> figures;   ///< file names (PNG) written into the output folder
};

/// The machine, compiler and source revision, for the report's header.
void fill_provenance(RunInfo& info);

void write_csv(const std::filesystem::path& path, const std::vector<Row>& rows);
void write_json(const std::filesystem::path& path, const PaperResults& results);
/// One result row as results.json writes it (columns in lab/metrics.json order);
/// a resumed run reads the same form back.
nlohmann::ordered_json row_json(const Row& r);
/// REPORT.md's text.
std::string report_markdown(const PaperResults& results);

/// The study's memory formula on 32-bit machines (bytes), or a negative
/// value for a structure it did not measure.
double study_memory_formula(const std::string& structure, std::size_t n);

}  // namespace broadphase::app
