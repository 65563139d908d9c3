#pragma once
// The virtual scanner: renders meshes into Kinect-like depth images (z-buffer, 640x480,
// ~525 px focal length) with a Kinect-like noise model, from the seed's ring of 12 views,
// and composes synthetic scenes (several meshes on a floor, one camera) with exact ground truth.
#include <cstdint>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/scanner/mesh.h"

namespace ism {

// Applied after rendering. min/max range always apply; `enabled = false` gives exact depth.
struct NoiseParams {
  bool enabled = true;
  // Axial noise sigma(z) = a + b * (z - 0.4)^2 (metres), Nguyen et al. 2012 for the Kinect.
  float sigma_a = 0.0012f;
  float sigma_b = 0.0019f;
  // Disparity quantisation: the Kinect measures disparity in 1/8 pixel steps over a 7.5 cm
  // baseline, so depth steps grow with z^2. disparity_step = 0 turns quantisation off.
  float baseline = 0.075f;
  float disparity_step = 0.125f;
  // The projector sits `baseline` to the camera's right (+x of the optical frame): surfaces the
  // camera sees but the projector's pattern does not reach return nothing, the band of missing
  // depth beside every occluding edge of a structured-light sensor (Landau, Choo and Beling,
  // "Simulating Kinect infrared and depth images", IEEE Trans. Cybernetics 2016).
  bool projector_shadow = true;
  // The Kinect finds each pixel's disparity by correlating a window of the projected dot pattern
  // (9 x 9 pixels), so its depth is not a pixel's own: edges are displaced by a fraction of a
  // pixel, and where the window straddles surfaces at different depths the match fails and the
  // pixel returns nothing, which eats the rims of objects and thins or breaks legs and rods. As
  // in the simulators of Barron and Malik (simkinect) and Handa et al. (ICL-NUIM, ICRA 2014):
  // each pixel reads the exact depth at a Gaussian offset of `pixel_shift` pixels, then keeps its
  // depth only if at least `window_agreement` of the window's samples (every other pixel, the
  // pattern's dots) lie within `window_tolerance` pixels of disparity of it. window = 0 turns the
  // window test off.
  float pixel_shift = 0.0f;  // 0.5 in simkinect and ICL-NUIM
  int window = 0;  // the Kinect's is 9
  float window_agreement = 0.5f;
  float window_tolerance = 0.5f;
  float min_depth = 0.5f;  // closer surfaces return nothing
  float max_depth = 6.0f;
  uint32_t seed = 1;
};

// A rendered frame: depth in metres (0 = no return), plus where the camera was.
struct DepthImage {
  CameraIntrinsics intrinsics;
  std::vector<float> depth;  // row-major, width * height
  // Camera frame: x right, y down, z forward (the optical frame).
  Eigen::Isometry3f camera_to_world = Eigen::Isometry3f::Identity();
};

// Camera at `eye` looking at `target` with world +z up.
Eigen::Isometry3f lookAt(const Eigen::Vector3f& eye, const Eigen::Vector3f& target);

struct ViewRingParams {
  int views = 12;                // around the object, evenly spaced in azimuth
  float elevation_deg = 20.0f;   // cameras slightly above the object (seed Fig. 3.4)
  float distance = 0.0f;         // camera to object centre (m); 0 = fit the object in view
  float min_distance = 0.0f;     // with distance 0: at least this far (m)
};
// Camera poses around the placed mesh, all looking at its bounding-box centre; view 0 faces
// the front (-y). The automatic distance fits the bounding sphere into `intrinsics`' view.
std::vector<Eigen::Isometry3f> viewRing(const Mesh& placed_mesh, const ViewRingParams& params,
                                        const CameraIntrinsics& intrinsics = {});

DepthImage renderDepth(const std::vector<const Mesh*>& meshes, const Eigen::Isometry3f& camera_to_world,
                       const CameraIntrinsics& intrinsics, const NoiseParams& noise);

// Depth image -> scene in world coordinates, organized, sensor origin = camera position.
Scene depthImageToWorldScene(const DepthImage& image, const std::string& source);
// Points of several views fused into a map: averaged per `spacing` cube (a TSDF averages the
// views' noise alike), no image grid, up +z, seen from `viewpoint`.
Scene fusedCloud(const std::vector<Eigen::Vector3f>& points, float spacing, const Eigen::Vector3f& viewpoint,
                 const std::string& source);
// Depth in metres -> 16-bit PNG (units per metre as given), for the sample scene and tests.
void saveDepthPng(const DepthImage& image, float units_per_metre, const std::string& path);

struct SceneObject {
  std::string category;
  Mesh mesh;              // already placed (placeMesh): +z up, standing on z=0
  float x = 0, y = 0;     // where on the floor
  float yaw = 0;          // rotation about +z (rad)
};

struct GroundTruthObject {
  std::string category;
  Eigen::Vector3f center;  // bounding-box centre of the placed mesh, world frame
  Eigen::Vector3f size;    // extent before yaw
  float yaw = 0;
  int points = 0;          // scene points that fall on this object
};

struct SyntheticSceneParams {
  float floor_size = 6.0f;  // square floor (m) centred at the origin, z = 0; 0 = no floor
  Eigen::Vector3f camera_eye{0.0f, -3.0f, 1.2f};
  Eigen::Vector3f camera_target{0.0f, 0.0f, 0.4f};
  CameraIntrinsics intrinsics;
  NoiseParams noise;
};

struct SyntheticScene {
  DepthImage depth;
  Scene scene;  // world frame, z up
  std::vector<GroundTruthObject> objects;
  // Per scene point, the index of the object it lies on, or -1 for the floor.
  std::vector<int> point_object;
};

// A square floor of `size` metres on z = 0, centred at the origin, facing up.
Mesh floorMesh(float size);

SyntheticScene composeScene(const std::vector<SceneObject>& objects, const SyntheticSceneParams& params);

}  // namespace ism
