// The packed cloud of a request -> ism::sceneFromPacked. Input layout: int32 width, int32 height,
// one flag byte (bit 0: colour), then float32 xyz per point followed by, with colour, uint8 rgb
// per point; the point count comes from the remaining length, so it disagrees with width*height
// as often as the fuzzer likes.
#include <cstring>
#include <vector>

#include "tests/fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr size_t kHeader = 2 * sizeof(int32_t) + 1;
  if (size < kHeader) return 0;
  int32_t width = 0;
  int32_t height = 0;
  std::memcpy(&width, data, sizeof width);
  std::memcpy(&height, data + sizeof width, sizeof height);
  const bool has_rgb = (data[2 * sizeof(int32_t)] & 1) != 0;
  const uint8_t* body = data + kHeader;
  const size_t body_size = size - kHeader;
  const size_t count = body_size / (3 * sizeof(float) + (has_rgb ? 3 : 0));
  // Copied so that the floats are aligned, as they are in a parsed protobuf.
  std::vector<float> xyz(3 * count);
  if (count > 0) std::memcpy(xyz.data(), body, xyz.size() * sizeof(float));
  const uint8_t* rgb_begin = body + xyz.size() * sizeof(float);
  const std::vector<uint8_t> rgb(rgb_begin, rgb_begin + (has_rgb ? 3 * count : 0));
  try {
    const ism::Scene scene = ism::sceneFromPacked(count == 0 ? nullptr : xyz.data(), count,
                                                  has_rgb ? rgb.data() : nullptr, width, height, "fuzz input");
    ism::fuzz::checkScene(scene);
    if (scene.cloud->size() > count) __builtin_trap();
  } catch (const ism::Error&) {
  }
  return 0;
}
