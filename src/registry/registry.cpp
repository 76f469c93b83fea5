#include <algorithm>
#include <broadphase/registry.hpp>
#include <charconv>
#include <cmath>
#include <sstream>
#include <vector>

#include "register.hpp"

namespace broadphase {

OptionReader::OptionReader(const OptionText& text, std::string structure)
    : text_(text), structure_(std::move(structure)) {}

OptionReader::OptionReader(const Config& c, std::string structure)
    : OptionReader(c.options, std::move(structure)) {}

namespace {
// The number `text` reads as, whole when `whole`; otherwise throws, naming
// the structure and the option. Ranges are the options struct's check().
double parse_number(const std::string& structure, const std::string& key, const std::string& text,
                    bool whole) {
  double v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc{} || end != text.data() + text.size() || !std::isfinite(v) ||
      (whole && (v != std::floor(v) || v < 0 || v >= 0x1p64))) {
    throw InvalidConfig(structure + ": option '" + key + "' must be " +
                        (whole ? "a whole number >= 0" : "a finite number") + ", got '" + text +
                        "'");
  }
  return v;
}
}  // namespace

double OptionReader::number(const std::string& key, double fallback) {
  read_.push_back(key);
  const auto it = text_.find(key);
  if (it == text_.end()) return fallback;
  return parse_number(structure_, key, it->second, false);
}

double OptionReader::number(const std::string& key, double fallback, double lo, double hi) {
  const double v = number(key, fallback);
  if (text_.count(key) != 0) detail::check_number(structure_, key, v, lo, hi);
  return v;
}

std::uint64_t OptionReader::integer(const std::string& key, std::uint64_t fallback) {
  read_.push_back(key);
  const auto it = text_.find(key);
  if (it == text_.end()) return fallback;
  return static_cast<std::uint64_t>(parse_number(structure_, key, it->second, true));
}

std::string OptionReader::choice(const std::string& key, const std::string& fallback,
                                 std::initializer_list<std::string_view> allowed) {
  read_.push_back(key);
  const auto it = text_.find(key);
  if (it == text_.end()) return fallback;
  for (std::string_view a : allowed)
    if (a == it->second) return it->second;
  std::string list;
  for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
  throw InvalidConfig(structure_ + ": option '" + key + "' must be one of " + list + ", got '" +
                      it->second + "'");
}

void OptionReader::finish() const {
  for (const auto& [key, value] : text_) {
    if (std::find(read_.begin(), read_.end(), key) == read_.end()) {
      std::string known;
      for (const std::string& k : read_) known += (known.empty() ? "" : ", ") + k;
      throw InvalidConfig(structure_ + ": unknown option '" + key + "'" +
                          (known.empty() ? " (it takes no options)" : " (known: " + known + ")"));
    }
  }
}

Registry Registry::library() {
  Registry r;
  detail::register_study(r);
  detail::register_grids(r);
  detail::register_trees(r);
  detail::register_fast(r);
  return r;
}

void Registry::add(StructureInfo info) {
  if (find(info.name) != nullptr)
    throw std::logic_error("broadphase: structure registered twice: " + info.name);
  entries_.push_back(std::move(info));
}

void Registry::add_alias(std::string alias, std::string name) {
  if (find(alias) != nullptr)
    throw std::logic_error("broadphase: alias names a structure already: " + alias);
  if (find(name) == nullptr)
    throw std::logic_error("broadphase: alias of an unknown structure: " + name);
  aliases_.push_back({std::move(alias), std::move(name)});
}

const StructureInfo* Registry::find(std::string_view name) const {
  for (const StructureInfo& e : entries_)
    if (e.name == name) return &e;
  for (const StructureAlias& a : aliases_)
    if (a.alias == name) return find(a.name);
  return nullptr;
}

std::string Registry::names() const {
  std::string out;
  for (const StructureInfo& e : entries_) out += (out.empty() ? "" : ", ") + e.name;
  return out;
}

std::unique_ptr<AnyBroadPhase> Registry::make(std::string_view spec, Config config) const {
  const std::size_t colon = spec.find(':');
  const std::string_view name = spec.substr(0, colon);
  const StructureInfo* info = find(name);
  if (info == nullptr)
    throw UnknownStructure("unknown structure '" + std::string(name) + "'; valid: " + names());
  // The deprecated Config::options, read once with the spec's options.
  OptionText text = std::move(config.options);
  config.options.clear();
  if (colon != std::string_view::npos) {
    std::string_view rest = spec.substr(colon + 1);
    std::vector<std::string_view> given;
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      const std::string_view item = rest.substr(0, comma);
      const std::size_t eq = item.find('=');
      if (eq == std::string_view::npos || eq == 0)
        throw InvalidConfig(std::string(name) + ": option '" + std::string(item) +
                            "' is not of the form key=value");
      const std::string_view key = item.substr(0, eq);
      if (std::find(given.begin(), given.end(), key) != given.end())
        throw InvalidConfig(std::string(name) + ": option '" + std::string(key) +
                            "' is given twice");
      given.push_back(key);
      text[std::string(key)] = std::string(item.substr(eq + 1));
      rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    }
  }
  // The Config and the option values are checked by the structure's
  // constructor (check_config, Options::check), the same way as for a
  // structure built directly.
  if (info->build) return info->build(config, text);
  config.options = std::move(text);  // an entry that reads its options from the Config
  return info->make(config);
}

std::unique_ptr<AnyBroadPhase> make_structure(std::string_view spec, const Config& config) {
  static const Registry registry = Registry::library();
  return registry.make(spec, config);
}

}  // namespace broadphase
