#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "lab.hpp"

namespace broadphase::app {

namespace {
std::string quoted(const std::string& s) {
  std::string out(1, '\'');
  for (char c : s) {
    if (c == '\'')
      out.append("'\\''");
    else
      out.push_back(c);
  }
  out.push_back('\'');
  return out;
}
}  // namespace

std::string plot_python() {
  static const std::string chosen = [] {
    std::vector<std::string> candidates;
    if (const char* env = std::getenv("BROADPHASE_PYTHON"); env != nullptr && *env != '\0')
      candidates.push_back(env);
    // Debian's interpreter first: python3-matplotlib installs into it, while
    // a python3 earlier on PATH (a virtualenv, pyenv) may not see it.
    candidates.push_back("/usr/bin/python3");
    candidates.push_back("python3");
    for (const std::string& c : candidates) {
      std::string probe = quoted(c);
      probe += " -c 'import matplotlib' >/dev/null 2>&1";
      if (std::system(probe.c_str()) == 0) return c;
    }
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
  std::string cmd = quoted(python);
  cmd.push_back(' ');
  cmd += quoted(path.string());
  for (const std::string& a : args) {
    cmd.push_back(' ');
    cmd += quoted(a);
  }
  if (std::system(cmd.c_str()) != 0) {
    std::fprintf(stderr, "broadphase: plot script %s failed\n", script.c_str());
    return false;
  }
  return true;
}

}  // namespace broadphase::app
