#pragma once
// The service's messages (proto/ism/v1/service.proto) and core's types, both ways, written once
// for the server and the clients. What comes from the wire is checked: a bad value throws
// ism::Error(kInvalidInput) naming the field and the value.
#include <optional>
#include <string>

#include "core/io/scene_bytes.h"
#include "core/recognition/recognizer.h"
#include "ism/v1/service.pb.h"

namespace ism::wire {

Eigen::Vector3f fromProto(const v1::Vec3& v);
// Not normalised: an all-zero (unset) quaternion stays zero for the caller to decide on.
Eigen::Quaternionf fromProto(const v1::Quaternion& q);
void toProto(const Eigen::Vector3f& v, v1::Vec3* out);
void toProto(const Eigen::Quaternionf& q, v1::Quaternion* out);

// fx, fy and depth_scale must be positive, cx and cy finite; `field` is the message's name in
// errors ("scene.depth.intrinsics").
DepthIntrinsics intrinsicsFromProto(const v1::CameraIntrinsics& in, const std::string& field);
v1::CameraIntrinsics intrinsicsToProto(const DepthIntrinsics& in);

// Scene.up: nullopt when unset. Not normalised (core does that), but it must be a direction:
// finite and not (nearly) zero, else kInvalidInput naming scene.up.
std::optional<Eigen::Vector3f> upFromProto(const v1::Scene& scene);

// RECOGNITION_PRESET_UNSPECIFIED is DEFAULT; a number this build does not know throws
// kInvalidInput naming options.preset.
RecognitionPreset presetFromProto(int value);
v1::RecognitionPreset toProto(RecognitionPreset preset);
v1::UpSource toProto(UpSource source);
std::optional<UpSource> upSourceFromProto(int value);  // nullopt for UNSPECIFIED and unknown numbers

// The options that pick what recognition answers (preset, min_confidence,
// one_answer_per_object, verify), with the defaults service.proto documents for unset fields. Throws
// kInvalidInput naming the field for an unknown preset or a min_confidence outside [0, 0.99].
void answerOptionsFromProto(const v1::RecognitionOptions& in, RecognitionOptions* out);
// Sets every one of them, so that the receiver need not know this side's defaults.
void answerOptionsToProto(const RecognitionOptions& in, v1::RecognitionOptions* out);

void toProto(const Gravity& gravity, v1::Gravity* out);
Gravity gravityFromProto(const v1::Gravity& in);  // an unknown or unset source reads as kAssumed

// Hypotheses that passed selection (or all, when selection was off) with their confidence and
// alternatives, the gravity used, stage timings and point counts. The model's name and version
// are the caller's to set.
void resultToProto(const RecognitionResult& result, v1::RecognitionResult* out);
RecognitionResult resultFromProto(const v1::RecognitionResult& in);

}  // namespace ism::wire
