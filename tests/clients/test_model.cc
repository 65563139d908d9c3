// Prints the folder of the model the client and deployment tests serve: the service tests'
// tiny two-category model (tests/service/service_fixture.cc), trained into the same build-tree
// cache on first use, so that whichever suite runs first trains it and the others reuse it.
#include <exception>
#include <iostream>

#include "tests/service/service_fixture.h"

int main() {
  try {
    std::cout << ism::testing::tinyModelDirectory() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "cannot make the test model: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
