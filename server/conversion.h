#pragma once
// Wire <-> core: requests become ism::Scene and ism::RecognitionOptions, results become
// messages. Every malformed field throws ism::Error naming the field and the value.
#include <grpcpp/support/byte_buffer.h>

#include <cstddef>
#include <string>

#include "core/recognition/recognizer.h"
#include "ism/v1/service.pb.h"
#include "server/model_registry.h"

namespace ism::server {

struct InputLimits {
  size_t max_points = 4'000'000;   // cloud points per scene
  size_t max_pixels = 4'194'304;   // depth pixels per image (2048 x 2048)
};

// The service decodes its messages itself rather than leaving it to gRPC, which answers a
// request protobuf cannot decode with UNIMPLEMENTED and no message, and reports such a message
// on a stream as the client's half-close. Throws kInvalidInput naming `what`, its size and
// the expected type.
void decodeMessage(const grpc::ByteBuffer& bytes, const std::string& what, google::protobuf::MessageLite* out);
void encodeMessage(const google::protobuf::MessageLite& message, grpc::ByteBuffer* out);

Scene sceneFromProto(const v1::Scene& scene, const InputLimits& limits);

// Unset strategy fields take the activation parameters the model's thresholds were computed
// with. Unknown categories fail here, before any work is done.
RecognitionOptions optionsFromProto(const v1::RecognitionOptions& options, const Model& model);

void resultToProto(const RecognitionResult& result, const LoadedModel& model, v1::RecognitionResult* out);

}  // namespace ism::server
