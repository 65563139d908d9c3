#pragma once
// Under the top: a table is a top on legs, so the sensor sees under it, the floor beneath it or
// whatever stands there (legs, chairs pushed in, boxes). A bed, a cabinet or a counter is a level
// top too, the height and depth of a table's, but a closed block: under its top nothing is
// measured, since the top hides the inside from above and its sides close it all round. A
// verified hypothesis of a flat-topped category (top_extent.h) whose measured top was found is
// dropped when fewer than min_open of the cells of its inner footprint hold a measured point
// from the floor up to `below` under the top. The floor under a table shows through below its
// edge from any sensor higher or lower than the top, and all round in a map. Another check of
// what supports what, as the open top and bare floor (Silberman, Hoiem, Kohli and Fergus, "Indoor
// segmentation and support inference from RGBD images", ECCV 2012). A closed block seen from the
// front shows its front face under the top, along the side facing the sensor: in a single view
// that strip does not count.
#include <vector>

#include <Eigen/Core>

#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct UnderTopParams {
  bool enabled = true;
  float inner = 0.8f;     // the share of the footprint's sides looked at (a block's sides stay out)
  float cell = 0.1f;      // cells of the inner footprint (m)
  float band = 0.05f;     // from this under the floor's height (m) ...
  float below = 0.15f;    // ... to this under the top (m; the top and its apron stay out)
  float min_open = 0.1f;  // of the inner footprint's cells holding a point there: below it, dropped
  // In a single view, points less than this (m) in from the side of the footprint facing the sensor
  // (sensorSide) do not open it: there stands the front of a dresser or a cabinet, its drawers
  // measured from the floor to the top, while the floor under a table shows through beyond its
  // edge. On the dev scans 0.15-0.5 m lost no true table (docs/EVALUATION.md, "A dresser's front
  // under a table's top"); 0.3 is the middle. 0: every point counts.
  float near_edge = 0.3f;
};

struct UnderTopCheck {
  bool looked = false;  // verified, upright and enabled
  float open = 0;       // the share of the inner footprint's cells holding a measured point under the top
  float min_open = 0;   // UnderTopParams::min_open
  bool closed() const { return looked && open < min_open; }
};

// The hypothesis' box is to run from the floor to the top the scene measured (extendToTop).
UnderTopCheck checkUnderTop(const VerificationScene& scene, const Hypothesis& hypothesis,
                            const UnderTopParams& params = {});

// The share of the inner footprint's cells holding a point from `band` under the floor to `below`
// under `top`: `points` (x, y about the footprint's centre along its sides, z above the floor) of a
// footprint `width` x `depth`.
float openUnderShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                     const UnderTopParams& params = {});

}  // namespace ism
