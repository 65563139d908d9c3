#pragma once
// A seat's run: how far the measured surface at seat height runs along a hypothesis' long side.
// A couch is long at seat height, a chair as wide as its seat, and so are the category's
// training shapes. Voting also puts couches on armchairs and chairs on sofas, and boxes over floor
// with nothing at seat height: there the scene shows much less than the shortest training shape
// at that height, or nothing at all under the box's middle. Each verified, upright hypothesis of a
// category that is not flat-topped (tables have their top, top_extent.h) is measured along its
// long side through its middle, within its depth, in a band of heights above the floor, and
// dropped when the run is shorter than min_share of the shortest run its category's training
// shapes show in the same band: the scene must not contradict the object's size (Hoiem, Efros
// and Hebert, "Putting objects in perspective", CVPR 2006, prune detections whose size the scene
// contradicts). On the dev clouds a share of 0.5 and of 0.7 gained alike, 0.85 dropped real
// two-seaters (docs/EVALUATION.md); the laxer is kept.
#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct SeatRunParams {
  bool enabled = true;
  // The band of heights above the floor (m): above a skirting and floor clutter, below a table's
  // top, where a chair's or a couch's seat and most of its body are.
  float from = 0.25f, to = 0.7f;
  float cell = 0.1f;     // cells along the long side (m); a cell holding a measured point is occupied
  int max_gap = 1;       // empty cells bridged within a run (a sparse sample, a thin gap between cushions)
  float reach = 4.0f;    // how far from the middle a run is followed (m)
  // A hypothesis whose run is shorter than this share of its category's shortest training run is
  // dropped: a real object is partly hidden, sparsely sampled or smaller than every training shape.
  float min_share = 0.5f;
};

// The run of occupied cells through the middle: the length (m) of the cells holding a point of
// `points` (x, y along the floor, z up) between `floor_z` + from and `floor_z` + to, within
// `half_width` of the line through `centre` along the unit vector `axis`, followed from the
// middle's two cells outward over gaps of up to max_gap cells. 0 when neither middle cell is
// occupied.
float seatRun(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector2f& centre, const Eigen::Vector2f& axis,
              float half_width, float floor_z, const SeatRunParams& params = {});

// The shortest seatRun of the category's training shapes along their long side (each in its own
// box, standing on z = 0), or nothing without shapes.
std::optional<float> trainingSeatRun(const CategoryModel& category, const SeatRunParams& params = {});

struct SeatRunCheck {
  bool looked = false;   // verified, upright, enabled, and the category has shapes
  float run = 0;         // measured along the hypothesis' long side (m)
  float required = 0;    // min_share of the training shapes' shortest run (m)
  bool tooShort() const { return looked && run < required; }
};

// The hypothesis' run in the scene against its category's `training_run` (trainingSeatRun, made
// once per category; nothing: not looked at).
SeatRunCheck checkSeatRun(const VerificationScene& scene, const Hypothesis& hypothesis,
                          const std::optional<float>& training_run, const SeatRunParams& params = {});

}  // namespace ism
