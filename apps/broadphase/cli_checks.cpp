#include "cli_checks.hpp"

#include <broadphase/scenes/excerpt.hpp>
#include <charconv>
#include <cmath>
#include <cstdint>

namespace broadphase::app {

std::string shorten_message(std::string_view message) {
  constexpr std::size_t kLongWord = 200, kKept = 40;
  static const char kHex[] = "0123456789abcdef";
  std::string out;
  std::size_t i = 0;
  while (i < message.size()) {
    std::size_t j = i;
    while (j < message.size() && message[j] != ' ' && message[j] != '\n') ++j;
    std::size_t end = j;
    if (j - i > kLongWord) {
      end = i + kKept;
      while (end > i && (static_cast<unsigned char>(message[end]) & 0xC0) == 0x80) --end;
    }
    for (std::size_t k = i; k < end; ++k) {
      const auto c = static_cast<unsigned char>(message[k]);
      if (c < 0x20 || c == 0x7f) {
        out += "\\x";
        out += kHex[c >> 4];
        out += kHex[c & 15];
      } else {
        out += static_cast<char>(c);
      }
    }
    if (end < j) out += "...";
    if (j < message.size()) out += message[j];
    i = j + 1;
  }
  return out;
}

namespace {

// The value as given when short and printable, else a quoted excerpt.
std::string shown(const std::string& text) {
  const std::string e = excerpt(text);
  return e.size() == text.size() + 2 ? text : e;
}

}  // namespace

CLI::Validator positive_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (ec != std::errc{} || end != text.data() + text.size() || !(v > 0) || !std::isfinite(v))
          return shown(text) + " is not a positive number";
        return {};
      },
      "");
}

CLI::Validator whole_number() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        std::uint64_t v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos)
          return shown(text) + " is not a whole number (digits only, no sign)";
        if (ec != std::errc{} || end != text.data() + text.size())
          return shown(text) + " is above the largest whole number, 2^64 - 1";
        return {};
      },
      "");
}

}  // namespace broadphase::app
