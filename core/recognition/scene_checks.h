#pragma once
// The scene's checks of one category's verified hypotheses, in the order recognition applies
// them after verification: a table's box becomes its measured top, the top must be there and of
// a training table's depth and height (top_extent.h), and something must be seen under it (under_top.h); a
// chair's or couch's run at seat height must be long enough (seat_run.h), its seat must be
// measured over its footprint (seat_area.h), a single view must not see through its fitted
// backrest (top_seen.h) and nothing may stand over its top (open_top.h); no
// hypothesis in a map may have bare floor in the middle of its footprint (bare_floor.h); a couch
// over a level top, or beside a mattress running on, is refuted (open_top.h). Recognition and the
// calibration share them (but the seat's area and the run-on, CalibrationParams::checks): a
// confidence is the chance that a hypothesis which passed them is right, so the calibration
// learns it from the peaks that pass them too.
#include <Eigen/Core>
#include <optional>

#include "core/model/model.h"
#include "core/recognition/bare_floor.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/open_top.h"
#include "core/recognition/seat_area.h"
#include "core/recognition/seat_run.h"
#include "core/recognition/seat_under_top.h"
#include "core/recognition/top_extent.h"
#include "core/recognition/top_seen.h"
#include "core/recognition/under_top.h"
#include "core/recognition/verification.h"

namespace ism {

struct SceneCheckParams {
  TopExtentParams top_extent;
  UnderTopParams under_top;
  SeatRunParams seat_run;
  SeatAreaParams seat_area;
  OpenTopParams open_top;
  TopSeenParams top_seen;
  BareFloorParams bare_floor;
  // Across categories, after every category's answers are checked: recognition only.
  SeatUnderTopParams seat_under_top;
};

// What the scene says of a hypothesis: nothing against it; it contradicts it (the hypothesis
// goes to the rejected answers); or it refutes it (it keeps its place when each object's answer
// is chosen, then is rejected: Hypothesis::refuted).
enum class SceneVerdict { kKept, kRejected, kRefuted };

// How far outside what the category's training objects measured a hypothesis may be and still
// pass a prior (m): the vote height test's tolerance and a bin.
float priorSlack(const Model& model, const CategoryModel& category);

// One category's checks, with what they need from its training shapes worked out once.
class SceneChecks {
 public:
  SceneChecks(const Model& model, const CategoryModel& category, const SceneCheckParams& params);
  // Checks a verified hypothesis; a table's box becomes its measured top on the way.
  SceneVerdict operator()(const VerificationScene& scene, Hypothesis& hypothesis, const Eigen::Matrix3f& to_gravity) const;

 private:
  const CategoryModel& category_;
  SceneCheckParams params_;
  float prior_slack_ = 0;
  bool flat_ = false;
  std::optional<float> training_run_;
  bool seat_area_ = false;
  bool covering_ = false;
};

}  // namespace ism
