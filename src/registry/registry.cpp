#include <algorithm>
#include <broadphase/registry.hpp>
#include <charconv>
#include <cmath>
#include <sstream>
#include <vector>

#include "register.hpp"

namespace broadphase {

OptionReader::OptionReader(const Config& c, std::string structure)
    : config_(c), structure_(std::move(structure)) {}

namespace {
// The value of option `key` when `text` is a number in [lo, hi] (a whole
// one when `whole`); otherwise throws, naming the structure and the range.
double parse_number(const std::string& structure, const std::string& key, const std::string& text,
                    double lo, double hi, bool whole) {
  double v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc{} || end != text.data() + text.size() || !std::isfinite(v) || v < lo ||
      v > hi || (whole && v != std::floor(v))) {
    std::ostringstream msg;
    msg.precision(10);  // whole bounds such as 2^24 in full
    msg << structure << ": option '" << key << "' must be " << (whole ? "an integer" : "a number")
        << " in [" << lo << ", " << hi << "], got '" << text << "'";
    throw UnknownStructure(msg.str());
  }
  return v;
}
}  // namespace

double OptionReader::number(const std::string& key, double fallback, double lo, double hi) {
  read_.push_back(key);
  const auto it = config_.options.find(key);
  if (it == config_.options.end()) return fallback;
  return parse_number(structure_, key, it->second, lo, hi, false);
}

std::int64_t OptionReader::integer(const std::string& key, std::int64_t fallback, std::int64_t lo,
                                   std::int64_t hi) {
  read_.push_back(key);
  const auto it = config_.options.find(key);
  if (it == config_.options.end()) return fallback;
  return static_cast<std::int64_t>(parse_number(
      structure_, key, it->second, static_cast<double>(lo), static_cast<double>(hi), true));
}

std::string OptionReader::choice(const std::string& key, const std::string& fallback,
                                 std::initializer_list<std::string_view> allowed) {
  read_.push_back(key);
  const auto it = config_.options.find(key);
  if (it == config_.options.end()) return fallback;
  for (std::string_view a : allowed)
    if (a == it->second) return it->second;
  std::string list;
  for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
  throw UnknownStructure(structure_ + ": option '" + key + "' must be one of " + list + ", got '" +
                         it->second + "'");
}

void OptionReader::finish() const {
  for (const auto& [key, value] : config_.options) {
    if (std::find(read_.begin(), read_.end(), key) == read_.end()) {
      std::string known;
      for (const std::string& k : read_) known += (known.empty() ? "" : ", ") + k;
      throw UnknownStructure(
          structure_ + ": unknown option '" + key + "'" +
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

const StructureInfo* Registry::find(std::string_view name) const {
  for (const StructureInfo& e : entries_)
    if (e.name == name) return &e;
  return nullptr;
}

std::string Registry::names() const {
  std::string out;
  for (const StructureInfo& e : entries_) out += (out.empty() ? "" : ", ") + e.name;
  return out;
}

namespace {
// Slot indices are 32 bits, one value of which means "null".
constexpr std::size_t kMaxObjects = Handle::kNullIndex;
}  // namespace

std::unique_ptr<AnyBroadPhase> Registry::make(std::string_view spec, Config config) const {
  const std::size_t colon = spec.find(':');
  const std::string_view name = spec.substr(0, colon);
  const StructureInfo* info = find(name);
  if (info == nullptr)
    throw UnknownStructure("unknown structure '" + std::string(name) + "'; valid: " + names());
  if (colon != std::string_view::npos) {
    std::string_view rest = spec.substr(colon + 1);
    std::vector<std::string_view> given;
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      const std::string_view item = rest.substr(0, comma);
      const std::size_t eq = item.find('=');
      if (eq == std::string_view::npos || eq == 0)
        throw UnknownStructure(std::string(name) + ": option '" + std::string(item) +
                               "' is not of the form key=value");
      const std::string_view key = item.substr(0, eq);
      if (std::find(given.begin(), given.end(), key) != given.end())
        throw UnknownStructure(std::string(name) + ": option '" + std::string(key) +
                               "' is given twice");
      given.push_back(key);
      config.options[std::string(key)] = std::string(item.substr(eq + 1));
      rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    }
  }
  if (config.expected_objects > kMaxObjects)
    throw UnknownStructure(std::string(name) + ": expected_objects " +
                           std::to_string(config.expected_objects) + " is more than the " +
                           std::to_string(kMaxObjects) + " objects a handle can name");
  const Aabb& w = config.world;
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(w.lo[a]) || !std::isfinite(w.hi[a]) || !(w.lo[a] < w.hi[a]))
      throw UnknownStructure(std::string(name) + ": the world box must be finite and non-empty");
  return info->make(config);
}

std::unique_ptr<AnyBroadPhase> make_structure(std::string_view spec, const Config& config) {
  static const Registry registry = Registry::library();
  return registry.make(spec, config);
}

}  // namespace broadphase
