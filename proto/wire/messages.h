#pragma once
// The service's messages (proto/ism/v1/service.proto) and core's types, both ways, written once
// for the server and the clients. What comes from the wire is checked: a bad value throws
// ism::Error(kInvalidInput) naming the field and the value.
#include <string>

#include "core/io/cloud_io.h"
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

// Hypotheses that passed selection (or all, when selection was off), stage timings and point
// counts. The model's name and version are the caller's to set.
void resultToProto(const RecognitionResult& result, v1::RecognitionResult* out);
RecognitionResult resultFromProto(const v1::RecognitionResult& in);

}  // namespace ism::wire
