#pragma once
// Bare floor: furniture covers the middle of its footprint, a chair or a couch with its seat, a
// table with its top, whether it stands on a closed base or on legs. Voting also puts couches over
// the gaps of a row of chairs, beside coffee tables and over empty floor, chairs and tables in the
// open: there the scene measures the floor in the middle of the box with nothing above it. Each
// verified, upright hypothesis in a map is dropped when max_bare or more of the cells of its inner
// footprint hold measured floor and no measured point above it, up to over its top. Floor seen
// under a couch on legs lies under its seat, so it does not count. Only for a category each of
// whose training shapes covers its own inner footprint (a category a user trains on coat stands
// does not). Like
// the open top, a check of what supports what (Silberman, Hoiem, Kohli and Fergus, "Indoor
// segmentation and support inference from RGBD images", ECCV 2012).
#include <vector>

#include <Eigen/Core>

#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct BareFloorParams {
  bool enabled = true;
  float inner = 0.6f;      // the share of the footprint's sides looked at (a box off its object's edges)
  float cell = 0.1f;       // cells of the inner footprint (m)
  float band = 0.05f;      // a measured point within this of the floor's height is floor (m)
  float body_from = 0.1f;  // a point from this above the floor (m) up to `over` above the top covers its cell
  float over = 0.3f;
  float max_bare = 0.3f;   // of the inner footprint's cells holding bare floor: at or over it, dropped
  // Only in maps (VerificationScene::map), which see surfaces from all round. In one frame a seat
  // may hide behind its backrest while the floor shows through the gap under it.
  bool maps_only = true;
};

struct BareFloorCheck {
  // Verified, upright, enabled, a map (maps_only), and the category's shapes cover their footprint.
  bool looked = false;
  float bare = 0;       // the share of the inner footprint's cells holding floor and nothing above it
  float max_bare = 0;   // BareFloorParams::max_bare
  bool bareFloor() const { return looked && bare >= max_bare; }
};

// `covering`: whether the category's shapes cover their footprint (footprintCoveredTrained); the
// check looks only then.
BareFloorCheck checkBareFloor(const VerificationScene& scene, const Hypothesis& hypothesis, bool covering,
                              const BareFloorParams& params = {});

// The share of the inner footprint's cells that hold floor (height within band of 0) and no point
// from body_from to `top` + over: `points` (x, y about the footprint's centre along its sides, z
// above the floor) of a footprint `width` x `depth`.
float bareShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                const BareFloorParams& params = {});

// Whether each of the category's training shapes covers its inner footprint: fewer than max_bare
// of its cells without surface over them (the shape has no floor); false without shapes or
// disabled.
bool footprintCoveredTrained(const CategoryModel& category, const BareFloorParams& params = {});

}  // namespace ism
