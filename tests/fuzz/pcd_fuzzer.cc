// PCD file bytes (ASCII, binary, binary_compressed headers and bodies) -> ism::loadCloudFile.
#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return ism::fuzz::loadCloudBytes(data, size, ".pcd");
}
