#pragma once
// Verification: voting proposes, the scene decides. Each hypothesis is checked against the depth
// the sensor measured: the category's training shapes (points on each training mesh, kept in the
// model) are placed upright on the floor at the hypothesis, turned through headings and moved a
// little, and seen from the sensor. Where a shape's front-most point in a pixel lies at the depth
// the sensor measured there, the scene agrees with it; where the sensor measured farther, it saw
// through the shape, and a solid object cannot be there (free-space violation); where it measured
// nearer, something else hides that part and nothing is said. The best pose's agreement is the
// hypothesis' fit, which the category's calibration turns into confidence with the vote score.
// This is hypothesis verification as in Aldoma, Tombari, Di Stefano and Vincze, "A global
// hypotheses verification method for 3D object recognition", ECCV 2012 (inliers and the
// free-space term), done per hypothesis on a depth buffer instead of jointly, with a pose search
// in the gravity frame (furniture only turns about up) and then ICP under the same constraint.
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>

#include "core/common/gravity_frame.h"
#include "core/common/types.h"
#include "core/common/upright_box.h"
#include "core/model/model.h"
#include "core/recognition/hypothesis.h"

namespace ism {

// Which of the depth test's terms the fit is made of (docs/EVALUATION.md has a row for each).
// kBoth: the share of the shape's seen pixels that the scene explains, where a pixel the sensor
// measured at the shape's depth explains it, one it saw through (measured farther) counts
// against, and one hidden behind nearer surface says nothing. kInliers: without free space, a
// seen-through pixel is not told from a hidden one; the fit is the share of the shape's pixels with
// a measurement that the scene explains. kFreeSpace: without inliers, only seeing through counts;
// the fit is the share of the shape's pixels with a measurement that the sensor did not see
// through. Poses are ranked by the same terms. A model is to be recognised with the terms its
// calibration was fitted with (ism-train and ism-eval --fit-terms).
enum class FitTerms { kBoth, kInliers, kFreeSpace };

struct VerificationParams {
  int coarse_yaws = 8;          // headings tried, evenly spaced, starting from the box's
  // The centre is also tried up to coarse_steps steps off along x and y, each step this share of
  // the category's longest side but at least min_shift. Steps growing with the size (0.12 of it,
  // two of them) fitted couches to desks on tum_desk more than they found the sample's couch.
  int coarse_steps = 1;
  float shift_fraction = 0.0f;
  float min_shift = 0.08f;
  int coarse_points = 64;       // shape points per pose in the coarse search
  int refined_poses = 3;        // best coarse poses refined
  float fine_yaw = 0.15f;       // refinement steps (rad, m)
  float fine_shift = 0.04f;
  // Shape points per pose when refining: the refined poses are ranked on the first
  // ranking_points of them, and the best is scored on max_points.
  int ranking_points = 200;
  int max_points = 800;
  // ICP after the grid: the best refined pose is moved by up to icp_iterations steps of
  // point-to-point ICP restricted to a turn about up and a shift along the floor (closed form in
  // the plane, Besl and McKay, "A method for registration of 3-D shapes", PAMI 1992), each of the
  // ranking points the sensor sees (a map: every one) paired with the nearest measured point
  // above the floor within icp_gate. The aligned pose replaces the grid's only when it ranks
  // better. 0: the grid's pose.
  int icp_iterations = 0;
  float icp_gate = 0.08f;
  FitTerms fit_terms = FitTerms::kBoth;
  // Depth agreement: margin + 2 sigma(z), sigma the Kinect's axial noise at depth z (Nguyen,
  // Izadi and Lovell, "Modeling Kinect sensor noise for improved 3D reconstruction and
  // tracking", 3DIMPVT 2012): 0.0012 + 0.0019 (z - 0.4)^2 m.
  float margin = 0.03f;
  size_t max_scene_points = 60'000;  // the scene is thinned to this many points by stride
  // A map (an unorganized cloud whose points surround its viewpoint: a fused room) is checked in
  // 3D, each shape point against the measured points within about a voxel of it. A map's
  // viewpoint is made up (viewpoint.h), so what a depth buffer from it calls seen through is
  // often a gap of the reconstruction or of a sparse sample, and what it calls hidden often a
  // surface the map does hold: on the dev ScanNet rooms the depth test's fit was higher on false
  // chairs than on true ones. false: every scene on a depth buffer from its viewpoint.
  bool maps_in_3d = true;
  // The fitted shape's points from this share of its height up are also scored on their own
  // (Verification::top_seen, top_consistent): its top part, a chair's backrest. Single views only,
  // the only ones top_seen.h reads; 0: not scored (both stay 0).
  float top_part = 0.75f;
};

// A global shape descriptor in the gravity frame: where an object's surface lies over height (12
// bins of a twelfth of the box's height, up to 1.2 of it) and over distance from the box's
// vertical axis (4 rings of a quarter of the half-sides, the box's edge the outermost), as a
// share of its points. A chair puts its surface at seat height and in its back, a table at the
// top and the rim, a cabinet everywhere on its front. It is the shells-and-sectors shape
// histogram of Ankerst, Kastenmueller, Kriegel and Seidl, "3D shape histograms for similarity
// search and classification in spatial databases", SSD 1999, cut along up instead of radially,
// since furniture stands upright. On the dev clouds' candidates with confidence above 0.1, the
// distance to the nearest training shape told true chairs from false ones with AUC 0.87, against
// 0.72 for the confidence, where PCL's ESF gave 0.74 at about 17 ms per candidate
// (docs/EVALUATION.md).
struct ShapeProfile {
  static constexpr int kHeights = 12, kRings = 4;
  std::array<float, kHeights * kRings> share{};
  int points = 0;
};

// The profile of `points` given in the box's frame: x, y from its vertical axis along its sides,
// z above its bottom; `size` its width, depth and height.
ShapeProfile shapeProfile(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& size);

// The chi-square distance of two profiles, sum (a - b)^2 / (a + b): 0 for the same, 2 for profiles
// with no bin in common.
float profileDistance(const ShapeProfile& a, const ShapeProfile& b);

// Which cubes of a grid lie within one cube of a measured point: one bit per cube over the
// points' bounding box, the cube's edge grown where the box would need more than kMaxCells.
class NearGrid {
 public:
  static constexpr size_t kMaxCells = size_t{1} << 28;  // 32 MB of bits
  NearGrid() = default;
  NearGrid(const std::vector<Eigen::Vector3f>& points, float cell);
  bool contains(const Eigen::Vector3f& p) const;
  float cell() const { return cell_; }

 private:
  Eigen::Vector3f min_ = Eigen::Vector3f::Zero();
  Eigen::Vector3i dims_ = Eigen::Vector3i::Zero();
  float cell_ = 0;
  std::vector<uint64_t> bits_;
};

// The scene as verification reads it: points relative to the sensor, in the gravity frame.
struct VerificationScene {
  std::vector<Eigen::Vector3f> points;
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();  // the sensor, scene coordinates
  Eigen::Matrix3f to_gravity = Eigen::Matrix3f::Identity();
  std::optional<float> floor_z;  // the floor's z relative to the sensor, gravity frame
  // A map (a fused room, its points all around the sensor) has no sensor whose line of sight
  // tells seen from hidden: its shapes are checked in 3D against `near`.
  bool map = false;
  NearGrid near;
};

VerificationScene makeVerificationScene(const Scene& scene, const std::optional<Gravity>& gravity,
                                        const VerificationParams& params = {});

// A hypothesis' upright box where the scene's checks read it: its centre relative to the sensor in
// the gravity frame, as VerificationScene::points are, and the floor's height there (the scene's
// floor, else the box's bottom).
struct SceneBox {
  UprightBox box;
  float floor_z = 0;
  float cos_yaw = 1, sin_yaw = 0;
  float top() const { return box.center.z() + box.size.z() / 2; }
  // `p` (VerificationScene::points' frame) in the box's own: along its width and its depth from
  // its centre, and its height above the floor.
  Eigen::Vector3f boxFrame(const Eigen::Vector3f& p) const {
    const float dx = p.x() - box.center.x(), dy = p.y() - box.center.y();
    return {cos_yaw * dx + sin_yaw * dy, -sin_yaw * dx + cos_yaw * dy, p.z() - floor_z};
  }
  // boxFrame's inverse: `q` (along the width and the depth from the centre, height above the
  // floor) in VerificationScene::points' frame.
  Eigen::Vector3f sceneFrame(const Eigen::Vector3f& q) const {
    return {box.center.x() + cos_yaw * q.x() - sin_yaw * q.y(), box.center.y() + sin_yaw * q.x() + cos_yaw * q.y(),
            q.z() + floor_z};
  }
  // Whether `p` (VerificationScene::points' frame) lies over the footprint, its sides shrunk to
  // `share` of theirs.
  bool overFootprint(const Eigen::Vector3f& p, float share = 1.0f) const {
    const Eigen::Vector3f q = boxFrame(p);
    return std::abs(q.x()) <= share * box.size.x() / 2 && std::abs(q.y()) <= share * box.size.y() / 2;
  }
  // How far `q` (boxFrame) lies in from `side` of the footprint (0, 1: its +x, -x end of the
  // width; 2, 3: its +y, -y end of the depth), and how far from the middle along that side.
  float inFrom(int side, const Eigen::Vector3f& q) const {
    const int axis = side / 2;
    return box.size[axis] / 2 - (side % 2 == 0 ? q[axis] : -q[axis]);
  }
  float alongSide(int side, const Eigen::Vector3f& q) const { return std::abs(q[1 - side / 2]); }
};

SceneBox sceneBox(const VerificationScene& scene, const Hypothesis& hypothesis);

// The side of the footprint (numbered as SceneBox::inFrom) that faces the sensor of a single view:
// the one the sensor lies farthest beyond. -1 in a map, whose viewpoint is made up (viewpoint.h),
// or with the sensor over the footprint.
int sensorSide(const VerificationScene& scene, const SceneBox& local);

// Whether `category` keeps training shapes to verify with. Objects without a surface are not
// tried (calibration holds out the shapes of the objects its rooms show).
bool hasShapes(const CategoryModel& category);

// The best pose of the category's shapes at `hypothesis` (its upright box gives the heading to
// start from and, without a floor, the bottom), or nothing when the hypothesis cannot be looked
// at: the sensor inside it, or too few scene points around it. Surface in `claimed` (cubes of 5 cm
// in the gravity frame relative to the sensor) was explained by a better hypothesis and counts
// neither way; the cubes the best pose explains go to `explained`.
std::optional<Verification> verify(const VerificationScene& scene, const CategoryModel& category,
                                   const Hypothesis& hypothesis, const VerificationParams& params = {},
                                   const std::unordered_set<uint64_t>* claimed = nullptr,
                                   std::unordered_set<uint64_t>* explained = nullptr);

// Sets each hypothesis' verification and puts its box on the best pose's shape, most confident
// first, so that of two hypotheses of a category on one surface only the better is credited with
// it (as the global verification of Aldoma et al. does with its multiple-assignment term). Sorts
// `hypotheses` by confidence. Hypotheses of categories without shapes are left as they are.
void verifyHypotheses(const VerificationScene& scene, const Model& model, std::vector<Hypothesis>& hypotheses,
                      const VerificationParams& params = {}, const ShouldStop& should_stop = {});

}  // namespace ism
