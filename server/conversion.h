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
  // Metres from the sensor origin beyond which a point is a stray measurement, not the room: a
  // Kinect sees up to ~10 m, and one point at 1e30 would stretch the voxel grid past its range.
  float max_range_m = 100.0f;
};

// The service decodes its messages itself rather than leaving it to gRPC, which answers a
// request protobuf cannot decode with UNIMPLEMENTED and no message, and reports such a message
// on a stream as the client's half-close. Throws kInvalidInput naming `what`, its size and
// the expected type.
void decodeMessage(const grpc::ByteBuffer& bytes, const std::string& what, google::protobuf::MessageLite* out);
void encodeMessage(const google::protobuf::MessageLite& message, grpc::ByteBuffer* out);

// Buffers a worker thread keeps from one decoded cloud to the next. A 640x480 frame is ~8 MB
// of points; allocated afresh on every call, that block would be handed back to the kernel and
// page-faulted in again on every frame, a cost a recognition in process never pays.
struct SceneBuffers {
  // Larger buffers are not kept: a worker holds at most ~36 MB for a scene it no longer needs.
  static constexpr size_t kMaxKeptPoints = size_t{1} << 20;

  Cloud::Ptr cloud;              // empty, its capacity kept; null when there is none to reuse
  std::vector<int> pixel_index;  // empty, its capacity kept

  // Takes back the cloud and pixel indices of a scene nobody uses any more (a cloud still
  // shared elsewhere is left alone).
  void recycle(Scene& scene);
};

// Points go straight from the request's bytes into the scene's cloud. With `buffers`, the
// cloud and pixel indices reuse its allocations (and take them: recycle them afterwards).
// `should_stop` ends a long PNG decode when the caller gives up.
Scene sceneFromProto(const v1::Scene& scene, const InputLimits& limits, SceneBuffers* buffers = nullptr,
                     const ShouldStop& should_stop = {});

// Drops the points farther than `max_range_m` from the scene's sensor origin (keeping an
// organized scene's pixel indices aligned) and returns how many. Throws kInvalidInput when none
// is left: such a scene is in other units than metres, or its sensor_origin is wrong.
size_t dropPointsBeyondRange(Scene* scene, float max_range_m);

// Unset strategy fields take the activation parameters the model's thresholds were computed
// with; the preset and its options are wire::answerOptionsFromProto's. Categories are core's to
// check (recognize() refuses unknown ones before any work).
RecognitionOptions optionsFromProto(const v1::RecognitionOptions& options, const Model& model);

// The result with the name and version of the model that answered.
void resultToProto(const RecognitionResult& result, const LoadedModel& model, v1::RecognitionResult* out);

}  // namespace ism::server
