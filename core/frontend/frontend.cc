#include "core/frontend/frontend.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <optional>
#include <vector>

#include "core/common/error.h"
#include "core/frontend/keypoints.h"
#include "core/frontend/range_image.h"
#include "core/frontend/shot.h"
#include "core/frontend/upright_geometry.h"
#include "core/gravity/viewpoint.h"

namespace ism {

Features describe(const Surface& surface, const std::vector<int>& keypoints, const ShotParams& params) {
  return computeShot(surface, keypoints, params);
}

FrontEndResult extractFeatures(const Scene& scene, const FrontEndParams& params, bool apply_smoothing,
                               StageTimings* timings, const ShouldStop& should_stop) {
  if (!scene.cloud || scene.cloud->empty()) {
    throw Error(ErrorCode::kInvalidInput, scene.source + ": the scene has no points");
  }
  FrontEndResult result;
  result.input_points = scene.cloud->size();
  throwIfStopped(should_stop, "front end start");
  XyzCloud::Ptr points;
  {
    ScopedStage stage(timings, "downsample");
    points = downsample(*scene.cloud, params.downsample);
  }
  throwIfStopped(should_stop, "downsample");
  if (apply_smoothing && params.smoothing.enabled) {
    {
      ScopedStage stage(timings, "smooth");
      points = smooth(*points, params.smoothing);
    }
    throwIfStopped(should_stop, "smooth");
  }
  result.surface_points = points->size();
  // Floor and walls: their points stay in the surface descriptors are computed over, but are
  // never keypoints.
  std::vector<PlaneLabel> planes;
  // The optical frame's up, -y, wherever the sensor's pose turns it.
  const Eigen::Vector3f sensor_up = scene.sensor_orientation * Eigen::Vector3f(0, -1, 0);
  if (params.gravity.enabled) {
    ScopedStage stage(timings, "gravity");
    std::vector<Eigen::Vector3f> positions(points->size());
    for (size_t i = 0; i < points->size(); ++i) positions[i] = (*points)[i].getVector3fMap();
    // What a sensor saw through a plane is only known where there was a sensor: a map's viewpoint
    // is made up (viewpoint.h), so its planes are not tested for it, as verification checks maps
    // without free space (VerificationParams::maps_in_3d).
    GravityParams gravity = params.gravity;
    if (gravity.wall_max_seen_through > 0 && isMap(scene)) {
      gravity.wall_max_seen_through = 0;
    }
    GravityResult found = estimateGravity(positions, scene.sensor_origin, sensor_up, scene.up, gravity);
    result.gravity = found.gravity;
    planes = std::move(found.labels);
  }
  const auto offPlanes = [&](std::vector<int> candidates, const std::vector<int>& point_of) {
    if (planes.empty()) return candidates;
    std::vector<int> kept;
    for (int k : candidates) {
      const int point = point_of.empty() ? k : point_of[static_cast<size_t>(k)];
      if (planes[static_cast<size_t>(point)] == PlaneLabel::kNone) kept.push_back(k);
    }
    return kept;
  };
  // Keypoints on the surface besides its contours (KeypointParams::surface_spacing): indices
  // into `points`, off the floor and walls; each needs a normal before it is taken.
  const auto surfaceSamples = [&] {
    if (params.keypoints.surface_spacing <= 0) return std::vector<int>{};
    std::vector<uint8_t> eligible(points->size(), 1);
    for (size_t i = 0; i < planes.size(); ++i) eligible[i] = planes[i] == PlaneLabel::kNone;
    // A cube needs a line of voxels across it (fewer are stray points), and a keypoint keeps a
    // voxel and a half from the floor and walls: their noise and the Kinect's depth steps scatter
    // points beyond the planes' tolerance (its steps are 5 cm apart at 4 m).
    const float leaf = params.downsample.leaf_size, spacing = params.keypoints.surface_spacing;
    return sampleSurfaceKeypoints(*points, eligible,
                                  {spacing, std::max(1, static_cast<int>(std::lround(spacing / leaf))), 1.5f * leaf});
  };
  const auto withSamples = [](std::vector<int> keypoints, const std::vector<int>& samples) {
    if (samples.empty()) return keypoints;
    std::vector<int> merged;
    std::set_union(keypoints.begin(), keypoints.end(), samples.begin(), samples.end(), std::back_inserter(merged));
    return merged;
  };
  std::vector<int> keypoints;
  const KeypointMethod method = resolveKeypointMethod(params.keypoints, scene);
  if (method == KeypointMethod::kBoundary) {
    std::vector<int> point_of_surface, index_in_surface;
    {
      ScopedStage stage(timings, "normals");
      NormalEstimator normals(*points, params.normals, scene.sensor_origin);
      normals.computeAll();
      result.surface = normals.surface(&index_in_surface);
      if (!planes.empty()) {
        point_of_surface.resize(result.surface->size());
        for (size_t i = 0; i < index_in_surface.size(); ++i) {
          if (index_in_surface[i] >= 0) point_of_surface[static_cast<size_t>(index_in_surface[i])] = static_cast<int>(i);
        }
      }
    }
    throwIfStopped(should_stop, "normals");
    {
      ScopedStage stage(timings, "keypoints");
      keypoints = offPlanes(detectKeypoints(scene, *result.surface, params.keypoints, params.downsample.leaf_size),
                            point_of_surface);
      std::vector<int> samples;
      for (int point : surfaceSamples()) {
        if (index_in_surface[static_cast<size_t>(point)] >= 0) samples.push_back(index_in_surface[static_cast<size_t>(point)]);
      }
      keypoints = withSamples(std::move(keypoints), samples);
    }
    throwIfStopped(should_stop, "keypoints");
  } else {
    // Keypoints first, then the normals SHOT reads around them.
    std::optional<NormalEstimator> normals;
    {
      ScopedStage stage(timings, "keypoints");
      normals.emplace(*points, params.normals, scene.sensor_origin);
      if (method == KeypointMethod::kRangeImage) {
        const Eigen::Vector3f up = result.gravity ? result.gravity->up : sensor_up;
        const Scene view = rangeImageView(*points, scene.sensor_origin, up, params.keypoints.range_image);
        if (view.image_width > 0) {
          keypoints = offPlanes(detectContourKeypoints(view, *normals, params.keypoints, params.downsample.leaf_size), {});
        }
      } else {
        keypoints = offPlanes(detectContourKeypoints(scene, *normals, params.keypoints, params.downsample.leaf_size), {});
      }
      std::vector<int> samples = surfaceSamples();
      if (!samples.empty()) {
        std::vector<uint8_t> wanted(points->size(), 0);
        for (int point : samples) wanted[static_cast<size_t>(point)] = 1;
        normals->compute(wanted);
        samples.erase(std::remove_if(samples.begin(), samples.end(),
                                     [&](int point) { return !normals->defined()[static_cast<size_t>(point)]; }),
                      samples.end());
        keypoints = withSamples(std::move(keypoints), samples);
      }
    }
    throwIfStopped(should_stop, "keypoints");
    {
      ScopedStage stage(timings, "normals");
      normals->computeNear(keypoints, params.shot.radius);
      std::vector<int> index_in_surface;
      result.surface = normals->surface(&index_in_surface);
      for (int& k : keypoints) k = index_in_surface[static_cast<size_t>(k)];
    }
    throwIfStopped(should_stop, "normals");
  }
  result.keypoint_candidates = keypoints.size();
  {
    ScopedStage stage(timings, "describe");
    std::vector<int> described;
    result.features = computeShot(*result.surface, keypoints, params.shot, &described);
    if (result.gravity) addUprightGeometry(*result.surface, described, *result.gravity, params.shot.radius, result.features);
  }
  result.features.organized = scene.image_width > 0;
  return result;
}

}  // namespace ism
