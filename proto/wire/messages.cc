#include "proto/wire/messages.h"

#include <cmath>
#include <cstdio>

#include "core/common/error.h"

namespace ism::wire {
namespace {

// Values in messages as a user typed them ("0.5", "nan"), not std::to_string's "0.500000".
std::string shortest(float v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace

Eigen::Vector3f fromProto(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

Eigen::Quaternionf fromProto(const v1::Quaternion& q) { return {q.w(), q.x(), q.y(), q.z()}; }

void toProto(const Eigen::Vector3f& v, v1::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

void toProto(const Eigen::Quaternionf& q, v1::Quaternion* out) {
  out->set_w(q.w());
  out->set_x(q.x());
  out->set_y(q.y());
  out->set_z(q.z());
}

DepthIntrinsics intrinsicsFromProto(const v1::CameraIntrinsics& in, const std::string& field) {
  const auto positive = [&](float v, const char* name) {
    if (!(std::isfinite(v) && v > 0)) {
      throw Error(ErrorCode::kInvalidInput, field + "." + name + " must be > 0, got " + std::to_string(v));
    }
    return v;
  };
  const auto finite = [&](float v, const char* name) {
    if (!std::isfinite(v)) throw Error(ErrorCode::kInvalidInput, field + "." + name + " is not finite");
    return v;
  };
  DepthIntrinsics out;
  out.fx = positive(in.fx(), "fx");
  out.fy = positive(in.fy(), "fy");
  out.cx = finite(in.cx(), "cx");
  out.cy = finite(in.cy(), "cy");
  out.depth_scale = positive(in.depth_scale(), "depth_scale");
  return out;
}

v1::CameraIntrinsics intrinsicsToProto(const DepthIntrinsics& in) {
  v1::CameraIntrinsics out;
  out.set_fx(in.fx);
  out.set_fy(in.fy);
  out.set_cx(in.cx);
  out.set_cy(in.cy);
  out.set_depth_scale(in.depth_scale);
  return out;
}

std::optional<Eigen::Vector3f> upFromProto(const v1::Scene& scene) {
  if (!scene.has_up()) return std::nullopt;
  const Eigen::Vector3f up = fromProto(scene.up());
  // The bound core's gravity stage refuses below; checked here so the message names the field.
  if (!(up.allFinite() && up.norm() > 1e-6f)) {
    throw Error(ErrorCode::kInvalidInput, "scene.up = (" + shortest(up.x()) + ", " + shortest(up.y()) + ", " +
                                              shortest(up.z()) +
                                              ") is not a direction: it must be finite and not zero (leave it unset "
                                              "to have the floor found)");
  }
  return up;
}

RecognitionPreset presetFromProto(int value) {
  switch (value) {
    case v1::RECOGNITION_PRESET_UNSPECIFIED:
    case v1::RECOGNITION_PRESET_DEFAULT: return RecognitionPreset::kDefault;
    case v1::RECOGNITION_PRESET_SEED: return RecognitionPreset::kSeed;
  }
  throw Error(ErrorCode::kInvalidInput,
              "options.preset " + std::to_string(value) + " is not supported (RECOGNITION_PRESET_DEFAULT or _SEED)");
}

v1::RecognitionPreset toProto(RecognitionPreset preset) {
  switch (preset) {
    case RecognitionPreset::kDefault: return v1::RECOGNITION_PRESET_DEFAULT;
    case RecognitionPreset::kSeed: return v1::RECOGNITION_PRESET_SEED;
  }
  return v1::RECOGNITION_PRESET_UNSPECIFIED;
}

v1::UpSource toProto(UpSource source) {
  switch (source) {
    case UpSource::kGiven: return v1::UP_SOURCE_GIVEN;
    case UpSource::kFloor: return v1::UP_SOURCE_FLOOR;
    case UpSource::kAssumed: return v1::UP_SOURCE_ASSUMED;
  }
  return v1::UP_SOURCE_UNSPECIFIED;
}

std::optional<UpSource> upSourceFromProto(int value) {
  switch (value) {
    case v1::UP_SOURCE_GIVEN: return UpSource::kGiven;
    case v1::UP_SOURCE_FLOOR: return UpSource::kFloor;
    case v1::UP_SOURCE_ASSUMED: return UpSource::kAssumed;
  }
  return std::nullopt;
}

void answerOptionsFromProto(const v1::RecognitionOptions& in, RecognitionOptions* out) {
  out->preset = presetFromProto(in.preset());
  if (in.has_min_confidence()) {
    // Core's bounds: a confidence of 1 is never reached, so a larger minimum would answer nothing.
    if (!(in.min_confidence() >= 0 && in.min_confidence() <= 0.99f)) {
      throw Error(ErrorCode::kInvalidInput,
                  "options.min_confidence = " + shortest(in.min_confidence()) + " is not in [0, 0.99]");
    }
    out->min_confidence = in.min_confidence();
  } else {
    out->min_confidence = RecognitionOptions{}.min_confidence;
  }
  out->one_answer_per_object = in.has_one_answer_per_object() ? in.one_answer_per_object() : true;
  out->verify = in.has_verify() ? in.verify() : true;
}

void answerOptionsToProto(const RecognitionOptions& in, v1::RecognitionOptions* out) {
  out->set_preset(toProto(in.preset));
  out->set_min_confidence(in.min_confidence);
  out->set_one_answer_per_object(in.one_answer_per_object);
  out->set_verify(in.verify);
}

void toProto(const Gravity& gravity, v1::Gravity* out) {
  toProto(gravity.up, out->mutable_up());
  out->set_source(toProto(gravity.source));
  if (gravity.floor_level) out->set_floor_level(*gravity.floor_level);
  out->set_floor_points(gravity.floor_points);
  out->set_wall_points(gravity.wall_points);
  out->set_walls(static_cast<uint32_t>(gravity.walls));
}

Gravity gravityFromProto(const v1::Gravity& in) {
  Gravity out;
  out.up = fromProto(in.up());
  out.source = upSourceFromProto(in.source()).value_or(UpSource::kAssumed);
  if (in.has_floor_level()) out.floor_level = in.floor_level();
  out.floor_points = in.floor_points();
  out.wall_points = in.wall_points();
  out.walls = static_cast<int>(in.walls());
  return out;
}

void resultToProto(const RecognitionResult& result, v1::RecognitionResult* out) {
  for (const auto& h : result.hypotheses) {
    auto* hp = out->add_hypotheses();
    hp->set_category(h.category);
    hp->set_score(h.score);
    hp->set_threshold(h.threshold);
    toProto(h.center, hp->mutable_center());
    toProto(h.box.center, hp->mutable_box()->mutable_center());
    toProto(h.box.size, hp->mutable_box()->mutable_size());
    toProto(h.box.rotation, hp->mutable_box()->mutable_rotation());
    hp->set_support(static_cast<uint32_t>(h.support));
    toProto(h.support_centroid, hp->mutable_support_centroid());
    hp->set_passed_selection(h.passed_selection);
    for (const auto& p : h.support_keypoints) toProto(p, hp->add_support_keypoints());
    hp->set_confidence(h.confidence);
    for (const auto& a : h.alternatives) {
      auto* ap = hp->add_alternatives();
      ap->set_category(a.category);
      ap->set_confidence(a.confidence);
    }
    hp->set_upright_box(h.upright_box);
    if (h.verification) {
      const Verification& v = *h.verification;
      auto* vp = hp->mutable_verification();
      vp->set_fit(v.fit());
      vp->set_seen(static_cast<uint32_t>(v.seen));
      vp->set_consistent(static_cast<uint32_t>(v.consistent));
      vp->set_claimed(static_cast<uint32_t>(v.claimed));
      vp->set_training_object(v.object);
      vp->set_yaw(v.yaw);
      vp->set_profile_distance(v.profile_distance);
      toProto(v.center, vp->mutable_center());
    }
  }
  if (result.gravity) toProto(*result.gravity, out->mutable_gravity());
  for (const auto& [stage, ms] : result.timings.stages) {
    auto* t = out->add_timings();
    t->set_stage(stage);
    t->set_ms(ms);
  }
  out->set_total_ms(result.timings.total());
  out->set_input_points(result.input_points);
  out->set_surface_points(result.surface_points);
  out->set_keypoints(result.keypoints);
}

RecognitionResult resultFromProto(const v1::RecognitionResult& in) {
  RecognitionResult out;
  for (const auto& h : in.hypotheses()) {
    Hypothesis& hypothesis = out.hypotheses.emplace_back();
    hypothesis.category = h.category();
    hypothesis.score = h.score();
    hypothesis.threshold = h.threshold();
    hypothesis.center = fromProto(h.center());
    hypothesis.box.center = fromProto(h.box().center());
    hypothesis.box.size = fromProto(h.box().size());
    hypothesis.box.rotation = fromProto(h.box().rotation());
    hypothesis.support = static_cast<int>(h.support());
    hypothesis.support_centroid = fromProto(h.support_centroid());
    hypothesis.passed_selection = h.passed_selection();
    for (const auto& p : h.support_keypoints()) hypothesis.support_keypoints.push_back(fromProto(p));
    hypothesis.confidence = h.confidence();
    for (const auto& a : h.alternatives()) hypothesis.alternatives.push_back({a.category(), a.confidence()});
    hypothesis.upright_box = h.upright_box();
    if (h.has_verification()) {
      const auto& vp = h.verification();
      Verification v;
      v.seen = static_cast<int>(vp.seen());
      v.consistent = static_cast<int>(vp.consistent());
      v.claimed = static_cast<int>(vp.claimed());
      v.object = vp.training_object();
      v.yaw = vp.yaw();
      v.profile_distance = vp.profile_distance();
      v.center = fromProto(vp.center());
      hypothesis.verification = v;
    }
  }
  if (in.has_gravity()) out.gravity = gravityFromProto(in.gravity());
  for (const auto& t : in.timings()) out.timings.add(t.stage(), t.ms());
  out.input_points = in.input_points();
  out.surface_points = in.surface_points();
  out.keypoints = in.keypoints();
  return out;
}

}  // namespace ism::wire
