#include <cstdlib>
#include <cstdio>
#include <filesystem>

#include "lab.hpp"

namespace broadphase::app {

namespace {
std::string quoted(const std::string& s) {
  std::string out(1, '\'');
  for (char c : s) {
    if (c == '\'') out.append("'\\''");
    else out.push_back(c);
  }
  out.push_back('\'');
  return out;
}
}  // namespace

bool run_plot_script(const std::string& script, const std::vector<std::string>& args) {
  const std::filesystem::path path = std::filesystem::path(BROADPHASE_SOURCE_DIR) / "tools" / script;
  if (!std::filesystem::exists(path)) {
    std::fprintf(stderr, "broadphase: plots skipped: %s not found\n", path.c_str());
    return false;
  }
  if (std::system("python3 -c 'import matplotlib' >/dev/null 2>&1") != 0) {
    std::fprintf(stderr, "broadphase: plots skipped: python3-matplotlib is not installed\n");
    return false;
  }
  std::string cmd = "python3 ";
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
