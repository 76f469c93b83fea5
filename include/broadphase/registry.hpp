/// \file registry.hpp
/// Structures by name: what `broadphase list` prints and `--algo` selects.
///
/// A name may carry options after a colon, `grid-dense:cell=25,storage=x`;
/// the registry splits the spec into OptionText and each structure's entry
/// reads the keys it knows straight into its typed options
/// (`Options::from`, src/registry/: the only place option strings are
/// parsed), rejects any other, and calls the typed constructor
/// `S(config, options)`. Config::options (deprecated) is merged into the
/// spec's text once, the spec winning for a key given in both.
#pragma once

#include <broadphase/config_error.hpp>
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

/// Thrown for an unknown structure name; the message lists the valid ones.
/// A bad option, an option not of the form key=value or a bad Config throws
/// InvalidConfig, of which this is the special case "no such structure"
/// (so `catch (const InvalidConfig&)` catches every error of a spec).
class UnknownStructure : public InvalidConfig {
 public:
  using InvalidConfig::InvalidConfig;
};

/// One entry of the registry.
struct StructureInfo {
  std::string name;
  std::string description;
  bool peer = false;  ///< another library's broad phase, run for comparison
  /// Makes the structure from a Config whose `options` hold its options as
  /// text (the form a peer's adapter takes).
  std::function<std::unique_ptr<AnyBroadPhase>(const Config&)> make;
  /// Makes the structure from a Config without options and its options as
  /// text, read straight into its typed options (detail::add_structure);
  /// empty for entries that only have `make`.
  std::function<std::unique_ptr<AnyBroadPhase>(const Config&, const OptionText&)> build = {};
};

/// An older name still accepted for a structure.
struct StructureAlias {
  std::string alias;  ///< the accepted name
  std::string name;   ///< the entry it stands for
};

/// Reads a structure's options from text (OptionText: a spec's, or the
/// deprecated Config::options) into typed values and rejects unknown keys. Ranges are not checked
/// here but by the options struct's check(), which the structure's constructor calls, so that a
/// value given in C++ and one given as text meet the same rule. Throws InvalidConfig.
class OptionReader {
 public:
  OptionReader(const OptionText& text, std::string structure);
  /// Reads `c.options` (for adapters built from a Config).
  OptionReader(const Config& c, std::string structure);
  /// A finite number, or `fallback` when absent.
  double number(const std::string& key, double fallback);
  /// A whole number >= 0, or `fallback` when absent.
  std::uint64_t integer(const std::string& key, std::uint64_t fallback);
  /// A number in [lo, hi], or `fallback` when absent: for options that have
  /// no options struct (the peers' adapters); NaN, infinite and subnormal
  /// values are refused.
  double number(const std::string& key, double fallback, double lo, double hi);
  /// One of `allowed`, or `fallback` when absent.
  std::string choice(const std::string& key, const std::string& fallback,
                     std::initializer_list<std::string_view> allowed);
  /// Throws InvalidConfig when a key was given that nobody read.
  void finish() const;

 private:
  const OptionText& text_;
  std::string structure_;
  std::vector<std::string> read_;
};

/// The structures known by name, in registration order.
class Registry {
 public:
  /// Every structure of the library (no peers).
  static Registry library();

  void add(StructureInfo info);
  /// Accepts `alias` as another name of the entry `name` (which must exist).
  void add_alias(std::string alias, std::string name);
  /// The entries, each once (aliases are not entries).
  const std::vector<StructureInfo>& entries() const { return entries_; }
  /// The accepted older names, in registration order.
  const std::vector<StructureAlias>& aliases() const { return aliases_; }
  /// Finds an entry by its bare name or an alias (no options); nullptr when
  /// unknown.
  const StructureInfo* find(std::string_view name) const;
  /// Makes `spec` (`name` or `name:key=value,...`). Throws UnknownStructure
  /// for an unknown name, InvalidConfig for a bad option or Config.
  std::unique_ptr<AnyBroadPhase> make(std::string_view spec, Config config = {}) const;
  /// The names, comma-separated, for error messages.
  std::string names() const;

 private:
  std::vector<StructureInfo> entries_;
  std::vector<StructureAlias> aliases_;
};

/// Convenience: makes a structure of the library by name.
std::unique_ptr<AnyBroadPhase> make_structure(std::string_view spec, const Config& config = {});

}  // namespace broadphase
