#pragma once
// Shared assertion: the call must throw ism::Error with the given code and a message that
// names what is wrong (contains `needle`).
#include <gtest/gtest.h>

#include <string>

#include "core/common/error.h"

namespace ism::testing {

template <class Call>
void expectError(Call call, ErrorCode code, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no error thrown; expected one mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace ism::testing
