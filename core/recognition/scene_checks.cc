#include "core/recognition/scene_checks.h"

namespace ism {

float priorSlack(const Model& model, const CategoryModel& category) {
  return model.voting.height_tolerance + category.bin_size;
}

SceneChecks::SceneChecks(const Model& model, const CategoryModel& category, const SceneCheckParams& params)
    : category_(category), params_(params), prior_slack_(priorSlack(model, category)) {
  flat_ = params.top_extent.enabled && flatTopped(category, params.top_extent);
  if (!flat_) training_run_ = trainingSeatRun(category, params.seat_run);
  seat_area_ = !flat_ && seatAreaTrained(category, params.seat_area);
  if (flat_ || !upperPartTrained(category, params.open_top)) params_.open_top.min_upper = 0;
  if (flat_ || !stepTopTrained(category, params.open_top)) params_.open_top.max_level = 0;
  covering_ = footprintCoveredTrained(category, params.bare_floor);
}

SceneVerdict SceneChecks::operator()(const VerificationScene& scene, Hypothesis& h,
                                     const Eigen::Matrix3f& to_gravity) const {
  if (flat_) {
    const TopFound top = extendToTop(scene, h, params_.top_extent);
    const bool topless = params_.top_extent.require_top && top == TopFound::kMissing;
    const bool closed = top == TopFound::kFound && checkUnderTop(scene, h, params_.under_top).closed();
    const bool off_prior = params_.top_extent.footprint_prior &&
                           !withinFootprintPrior(h, category_, to_gravity, prior_slack_);
    const bool off_height = top == TopFound::kFound && params_.top_extent.height_slack > 0 &&
                            !withinHeightPrior(h, category_, to_gravity, params_.top_extent.height_slack);
    if (topless || closed || off_prior || off_height ||
        checkBareFloor(scene, h, covering_, params_.bare_floor).bareFloor()) {
      return SceneVerdict::kRejected;
    }
    return SceneVerdict::kKept;
  }
  if (checkSeatRun(scene, h, training_run_, params_.seat_run).tooShort() ||
      checkSeatArea(scene, h, seat_area_, params_.seat_area).bare() ||
      checkTopSeen(scene, h, params_.top_seen).seenThrough()) {
    return SceneVerdict::kRejected;
  }
  const int object = h.verification ? h.verification->object : -1;
  const TrainingObject* fitted =
      object >= 0 && static_cast<size_t>(object) < category_.objects.size() ? &category_.objects[static_cast<size_t>(object)] : nullptr;
  const OpenTopCheck top = checkOpenTop(scene, h, params_.open_top, fitted);
  if (top.contradicted() || checkBareFloor(scene, h, covering_, params_.bare_floor).bareFloor()) {
    return SceneVerdict::kRejected;
  }
  return top.refuted() ? SceneVerdict::kRefuted : SceneVerdict::kKept;
}

}  // namespace ism
