// broadphase: the command line of the library and its lab.
#include <CLI/CLI.hpp>
#include <broadphase/scenes/scene.hpp>
#include <broadphase/version.hpp>
#include <cstdio>
#include <exception>
#include <new>

#include "cli_checks.hpp"
#include "commands.hpp"
#include "interrupt.hpp"

namespace {

// Exit statuses, the same for every subcommand (README, "Command line").
constexpr int kExitFailure = 1;  // bad input file, failed run, failed write
constexpr int kExitUsage = 2;    // wrong command line

void report(const char* message) {
  std::fprintf(stderr, "broadphase: error: %s\n",
               broadphase::app::shorten_message(message).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"broadphase: exact, fast, measured broad-phase collision detection"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("broadphase ") + BROADPHASE_VERSION_STRING,
                       "Print the version and exit");
  app.footer(
      "Exit status: 0 done; 1 bad input file or failed run (a write error, structures that "
      "disagree, an experiment that failed); 2 wrong command line; 130 interrupted (Ctrl-C), "
      "143 terminated.");
  broadphase::app::add_list_command(app);
  broadphase::app::add_run_command(app);
  broadphase::app::add_gen_command(app);
  broadphase::app::add_paper_command(app);
  broadphase::app::add_sim_command(app);
  broadphase::app::add_draw_command(app);
  broadphase::app::add_advise_command(app);
  // Ctrl-C and SIGTERM remove the outputs still being written, stop the
  // plotting child, and end the process by the signal.
  broadphase::app::install_interrupt_handlers();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // CLI11's own codes (105 conversion, 106 required, 109 extras, ...)
    // are all a wrong command line.
    std::fprintf(stderr, "broadphase: error: %s\nRun with --help for more information.\n",
                 broadphase::app::shorten_message(e.what()).c_str());
    return kExitUsage;
  } catch (const broadphase::app::UsageError& e) {
    report(e.what());
    return kExitUsage;
  } catch (const broadphase::InvalidConfig& e) {
    report(e.what());
    return kExitUsage;
  } catch (const broadphase::SceneError& e) {
    report(e.what());
    return kExitFailure;
  } catch (const std::bad_alloc&) {
    report("out of memory (the scene or the run is too large for this machine)");
    return kExitFailure;
  } catch (const std::exception& e) {
    report(e.what());
    return kExitFailure;
  }
  return 0;
}
