// The service's request decoding: bytes -> ism.v1.RecognizeRequest -> the core Scene
// (ism::server::sceneFromProto), as the server does before any recognition work. Limits are
// smaller than the server's defaults so that accepted inputs stay cheap per execution.
#include <google/protobuf/stubs/logging.h>

#include <cstddef>
#include <cstdint>

#include "server/conversion.h"
#include "tests/fuzz/fuzz_common.h"

// protobuf logs every string field that is not UTF-8, which most mutations produce.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  ism::v1::RecognizeRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return 0;
  ism::server::InputLimits limits;
  limits.max_points = 1 << 16;
  limits.max_pixels = 1 << 16;
  try {
    ism::fuzz::checkScene(ism::server::sceneFromProto(request.scene(), limits));
  } catch (const ism::Error&) {
  }
  return 0;
}
