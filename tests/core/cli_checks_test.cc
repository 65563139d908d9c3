// The command-line checks shared by the tools, the client and the server: what they let through,
// and that a refusal names what was wanted and what was given.
#include "core/common/cli_checks.h"

#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace ism {
namespace {

// Parses `--n VALUE` with `check`; the refusal's message, or empty when it was accepted.
std::string refusal(const CLI::Validator& check, const std::string& value) {
  CLI::App app;
  double n = 0;
  app.add_option("--n", n)->check(check);
  std::vector<std::string> args = {value, "--n"};  // CLI11 parses a reversed vector
  try {
    app.parse(args);
  } catch (const CLI::ParseError& e) {
    return e.what();
  }
  return {};
}

TEST(CliChecks, PositiveRefusesZeroAndBelowAndSaysWhy) {
  EXPECT_EQ(refusal(cli::positive(), "0.25"), "");
  EXPECT_EQ(refusal(cli::positive(), "3"), "");
  EXPECT_EQ(refusal(cli::positive(), "0"), "--n: must be > 0, got 0");
  EXPECT_EQ(refusal(cli::positive(), "-2"), "--n: must be > 0, got -2");
}

TEST(CliChecks, NonNegativeTakesZeroAndSaysWhyItRefusesLess) {
  EXPECT_EQ(refusal(cli::nonNegative(), "0"), "");
  EXPECT_EQ(refusal(cli::nonNegative(), "1e3"), "");
  EXPECT_EQ(refusal(cli::nonNegative(), "-0.5"), "--n: must be >= 0, got -0.5");
}

TEST(CliChecks, TextThatIsNoNumberIsNamed) {
  EXPECT_EQ(refusal(cli::nonNegative(), "ten"), "--n: not a number: 'ten'");
  EXPECT_EQ(refusal(cli::positive(), "3m"), "--n: not a number: '3m'");
}

}  // namespace
}  // namespace ism
