/// \file lab/excerpt.hpp
/// Quoting what the user gave in a message: a short excerpt, escaped, so a
/// 10 MB token or a control byte never reaches the terminal whole.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace broadphase {

/// At most `max` bytes of `text`, in single quotes, with bytes below 0x20,
/// 0x7f and a quote written as \xNN, and "..." after the quote when cut.
/// Bytes of 0x80 and above (UTF-8) pass through, except that a cut never
/// splits a multi-byte sequence.
inline std::string excerpt(std::string_view text, std::size_t max = 40) {
  std::size_t n = text.size() <= max ? text.size() : max;
  if (n < text.size())
    while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n;
  std::string out = "'";
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7f || c == '\'') {
      static const char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    } else {
      out += static_cast<char>(c);
    }
  }
  out += '\'';
  if (n < text.size()) out += "...";
  return out;
}

}  // namespace broadphase
