#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "interrupt.hpp"
#include "lab.hpp"

namespace broadphase::app {

std::string plot_python() {
  static const std::string chosen = [] {
    std::vector<std::string> candidates;
    if (const char* env = std::getenv("BROADPHASE_PYTHON"); env != nullptr && *env != '\0')
      candidates.push_back(env);
    // Debian's interpreter first: python3-matplotlib installs into it, while
    // a python3 earlier on PATH (a virtualenv, pyenv) may not see it.
    candidates.push_back("/usr/bin/python3");
    candidates.push_back("python3");
    for (const std::string& c : candidates)
      if (run_process({c, "-c", "import matplotlib"}, true).ok()) return c;
    return std::string();
  }();
  return chosen;
}

bool run_plot_script(const std::string& script, const std::vector<std::string>& args) {
  const std::filesystem::path path =
      std::filesystem::path(BROADPHASE_SOURCE_DIR) / "tools" / script;
  if (!std::filesystem::exists(path)) {
    std::fprintf(stderr, "broadphase: plots skipped: %s not found\n", path.c_str());
    return false;
  }
  const std::string python = plot_python();
  if (python.empty()) {
    std::fprintf(stderr, "broadphase: plots skipped: python3-matplotlib is not installed\n");
    return false;
  }
  std::vector<std::string> argv = {python, path.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  const ProcessStatus st = run_process(argv);
  // A script ended by Ctrl-C or SIGTERM was interrupted: not a failure to
  // report as a missing matplotlib, and not one to continue after.
  if (st.signal == SIGINT || st.signal == SIGTERM)
    throw ChildInterrupted("plot script " + script + " was " + st.describe());
  if (!st.ok()) {
    std::fprintf(stderr, "broadphase: plot script %s failed: %s\n", script.c_str(),
                 st.describe().c_str());
    return false;
  }
  return true;
}

}  // namespace broadphase::app
