// PNG bytes -> ism::decodeDepthPng16 and, for images it accepts, the back-projection the service
// runs on depth requests (ism::decodeDepthPng).
#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    const ism::DepthPng image = ism::decodeDepthPng16(bytes, "fuzz input");
    if (image.pixels.size() != static_cast<size_t>(image.width) * image.height) __builtin_trap();
    ism::fuzz::checkScene(ism::decodeDepthPng(bytes, ism::DepthIntrinsics{}, "fuzz input"));
  } catch (const ism::Error&) {
  }
  return 0;
}
