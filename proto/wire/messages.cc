#include "proto/wire/messages.h"

#include <cmath>

#include "core/common/error.h"

namespace ism::wire {

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
  }
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
  }
  for (const auto& t : in.timings()) out.timings.add(t.stage(), t.ms());
  out.input_points = in.input_points();
  out.surface_points = in.surface_points();
  out.keypoints = in.keypoints();
  return out;
}

}  // namespace ism::wire
