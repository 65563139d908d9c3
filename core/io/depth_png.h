#pragma once
// 16-bit single-channel PNG encode/decode in memory (libpng). Depth frames travel as these
// (TUM RGB-D, OpenNI recordings, the service's PNG input) and the virtual scanner writes them.
#include <cstdint>
#include <string>
#include <vector>

#include "core/common/types.h"

namespace ism {

struct DepthPng {
  int width = 0;
  int height = 0;
  std::vector<uint16_t> pixels;  // row-major, raw sensor units
};

// Throws Error(kInvalidInput) naming `source` when the bytes are not a PNG, or not a
// single-channel 16-bit one (the message says what it is instead), or when its image data
// inflates to more than its header's size holds (a decompression bomb is refused after that
// many bytes, not inflated to the end). `should_stop` is asked between rows and every few MB
// inflated: true throws Error(kCancelled).
DepthPng decodeDepthPng16(const std::string& bytes, const std::string& source, const ShouldStop& should_stop = {});
std::string encodeDepthPng16(const DepthPng& image);

}  // namespace ism
