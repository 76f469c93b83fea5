// What every subcommand checks on its command line, and how messages quote
// what the user gave.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <string_view>

namespace broadphase::app {

/// A message fit for one terminal line: control bytes escaped as \xNN and
/// every word (a run without spaces) longer than 200 bytes cut to its first
/// 40 and "...": a 100 kB argument or token is never echoed whole. Paths and
/// lists of names are shorter than the cut and stay whole.
std::string shorten_message(std::string_view message);

/// A number > 0 and finite, e.g. --dt. Its message names a short bound
/// ("--dt: 0 is not a positive number") instead of CLI11's range up to
/// DBL_MAX in 309 digits.
CLI::Validator positive_number();

/// A whole number of decimal digits only (a seed, a count): refuses "-1",
/// which the conversion to an unsigned type would take as 2^64 - 1.
CLI::Validator whole_number();

}  // namespace broadphase::app
