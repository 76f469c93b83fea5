// `paper`: the command line of the lab's main job. The job itself, its
// steps and its budget are the lab's (lab/paper.cpp); this file only reads
// the options and hands them over.
#include <CLI/CLI.hpp>
#include <memory>

#include "cli_checks.hpp"
#include "commands.hpp"
#include "paper.hpp"
#include "paper_steps.hpp"

namespace broadphase::app {

void add_paper_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "paper", "Run the study's tests on every structure and write results, figures and REPORT.md");
  auto o = std::make_shared<PaperOptions>();
  auto* quick = cmd->add_flag("--quick", o->quick,
                              "Small sizes and few repetitions: under a minute (what CI runs)");
  auto* out = cmd->add_option("--out", o->out, "Output directory (default results/<date>-<host>/)");
  auto* algos =
      cmd->add_option("--algos", o->algos,
                      "Structures to run, comma-separated, with options as name:key=value,... "
                      "(default: every registered structure, and `arrays`, the lean path over "
                      "the caller's arrays, in the frame time and memory)");
  auto* max_n =
      cmd->add_option(
             "--max-n", o->max_n,
             "Largest number of objects to run (at least 50), in the study and in every experiment")
          ->check(whole_number());
  auto* seed = cmd->add_option("--seed", o->seed, "Random seed of the scenes")
                   ->default_val(1)
                   ->check(whole_number());
  auto* budget =
      cmd->add_option("--budget", o->budget,
                      "Seconds the whole run should take at most (default 1500, 35 with --quick); "
                      "structures whose projected time does not fit are skipped at large sizes");
  auto* peers =
      cmd->add_flag("--peers,!--no-peers", o->peers, "Include the peer libraries (default: yes)");
  cmd->add_option("--resume", o->resume,
                  "Finish the interrupted run in DIR with its options, without redoing the steps "
                  "it has done (paper-state.json and RUN-INCOMPLETE in DIR say which)")
      ->type_name("DIR")
      ->excludes(quick, out, algos, max_n, seed, budget, peers);
  cmd->callback([o, max_n] {
    o->max_n_given = max_n->count() > 0;
    if (!o->resume.empty()) apply_recorded_options(*o, PaperSteps::recorded_options(o->resume));
    run_paper(*o);
  });
}

}  // namespace broadphase::app
