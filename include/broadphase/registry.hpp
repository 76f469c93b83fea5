/// \file registry.hpp
/// Structures by name: what `broadphase list` prints and `--algo` selects.
///
/// A name may carry options after a colon, `grid-dense:cell=25,storage=x`;
/// each structure reads the keys it knows and rejects any other.
#pragma once

#include <broadphase/structure.hpp>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace broadphase {

/// Thrown for an unknown structure name or a bad option; the message names
/// what was wrong and, for an unknown name, lists the valid ones.
class UnknownStructure : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// One entry of the registry.
struct StructureInfo {
  std::string name;
  std::string description;
  bool peer = false;  ///< another library's broad phase, run for comparison
  std::function<std::unique_ptr<AnyBroadPhase>(const Config&)> make;
};

/// Reads a structure's options from a Config and rejects unknown keys.
class OptionReader {
 public:
  OptionReader(const Config& c, std::string structure);
  /// A number in [lo, hi], or `fallback` when absent.
  double number(const std::string& key, double fallback, double lo, double hi);
  /// A whole number in [lo, hi], or `fallback` when absent.
  std::int64_t integer(const std::string& key, std::int64_t fallback, std::int64_t lo,
                       std::int64_t hi);
  /// One of `allowed`, or `fallback` when absent.
  std::string choice(const std::string& key, const std::string& fallback,
                     std::initializer_list<std::string_view> allowed);
  /// Throws UnknownStructure when a key was given that nobody read.
  void finish() const;

 private:
  const Config& config_;
  std::string structure_;
  std::vector<std::string> read_;
};

/// The structures known by name, in registration order.
class Registry {
 public:
  /// Every structure of the library (no peers).
  static Registry library();

  void add(StructureInfo info);
  const std::vector<StructureInfo>& entries() const { return entries_; }
  /// Finds an entry by its bare name (no options); nullptr when unknown.
  const StructureInfo* find(std::string_view name) const;
  /// Makes `spec` (`name` or `name:key=value,...`). Throws UnknownStructure.
  std::unique_ptr<AnyBroadPhase> make(std::string_view spec, Config config = {}) const;
  /// The names, comma-separated, for error messages.
  std::string names() const;

 private:
  std::vector<StructureInfo> entries_;
};

/// Convenience: makes a structure of the library by name.
std::unique_ptr<AnyBroadPhase> make_structure(std::string_view spec, const Config& config = {});

}  // namespace broadphase
