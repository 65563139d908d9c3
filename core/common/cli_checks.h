#pragma once
// Checks of command-line numbers for the tools, the client and the server whose messages say what
// was wanted ("--calibration-rooms: must be > 0, got 0"): CLI11's PositiveNumber and
// NonNegativeNumber print their range digit by digit, up to 1.797...e308.
#include <cstdlib>
#include <string>

#include <CLI/CLI.hpp>

namespace ism::cli {

namespace detail {
inline CLI::Validator atLeast(bool strictly, const char* name) {
  return CLI::Validator(
      [strictly](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') return "not a number: '" + text + "'";
        if (strictly ? value > 0 : value >= 0) return {};
        return std::string(strictly ? "must be > 0" : "must be >= 0") + ", got " + text;
      },
      name);
}
}  // namespace detail

inline CLI::Validator positive() { return detail::atLeast(true, "POSITIVE"); }
inline CLI::Validator nonNegative() { return detail::atLeast(false, "NONNEGATIVE"); }

}  // namespace ism::cli
