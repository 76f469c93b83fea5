// A replay of one structure on one scene, behind an interface free of the
// library's namespace, so that two builds of the library (renamed
// namespaces) can be driven from one process. See ab.sh.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

struct Runner {
  virtual ~Runner() = default;
  /// Evaluates the next frame; returns the structure's time for it in ms.
  virtual double frame() = 0;
  /// The pair hash of the last frame.
  virtual std::uint64_t hash() const = 0;
};

std::unique_ptr<Runner> make_runner_A(const std::string& scene, const std::string& spec);
std::unique_ptr<Runner> make_runner_B(const std::string& scene, const std::string& spec);
