// Model file bytes -> ism::parseModel. The payload's CRC-32 stops almost every mutation at the
// envelope, so the first byte picks what the rest is: odd = a ModelData payload, wrapped here in
// a valid envelope so that the fuzzer reaches the payload checks; even = a whole model file,
// for the envelope checks themselves.
#include <google/protobuf/stubs/logging.h>
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/common/error.h"
#include "core/model/model_file.h"
#include "ism/v1/model.pb.h"

// protobuf logs every string field that is not UTF-8, which most mutations produce.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  if (data[0] & 1) {
    ism::v1::ModelFile file;
    file.set_magic("ISM-MODEL");
    file.set_format_version(ism::kModelFormatVersion);
    file.set_payload_crc32(
        static_cast<uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(bytes.size()))));
    file.set_payload(std::move(bytes));
    bytes = file.SerializeAsString();
  }
  try {
    ism::parseModel(bytes, "fuzz input");
  } catch (const ism::Error&) {
  }
  return 0;
}
