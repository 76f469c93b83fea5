// broadphase: the command line of the library and its lab.
#include <broadphase/lab/scene.hpp>
#include <cstdio>
#include <exception>
#include <new>

#include "commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"broadphase: exact, fast, measured broad-phase collision detection"};
  app.require_subcommand(1);
  broadphase::app::add_list_command(app);
  broadphase::app::add_run_command(app);
  broadphase::app::add_gen_command(app);
  broadphase::app::add_paper_command(app);
  broadphase::app::add_sim_command(app);
  broadphase::app::add_draw_command(app);
  broadphase::app::add_advise_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const broadphase::app::UsageError& e) {
    std::fprintf(stderr, "broadphase: error: %s\n", e.what());
    return 2;
  } catch (const broadphase::InvalidConfig& e) {
    std::fprintf(stderr, "broadphase: error: %s\n", e.what());
    return 2;
  } catch (const broadphase::SceneError& e) {
    std::fprintf(stderr, "broadphase: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "broadphase: error: out of memory (the scene or the run is too large "
                 "for this machine)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "broadphase: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
