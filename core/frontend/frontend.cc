#include "core/frontend/frontend.h"

#include <optional>
#include <vector>

#include "core/common/error.h"
#include "core/frontend/shot.h"

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
  std::vector<int> keypoints;
  if (resolveKeypointMethod(params.keypoints.method, scene) == KeypointMethod::kBoundary) {
    {
      ScopedStage stage(timings, "normals");
      result.surface = estimateNormals(*points, params.normals, scene.sensor_origin);
    }
    throwIfStopped(should_stop, "normals");
    {
      ScopedStage stage(timings, "keypoints");
      keypoints = detectKeypoints(scene, *result.surface, params.keypoints, params.downsample.leaf_size);
    }
    throwIfStopped(should_stop, "keypoints");
  } else {
    // Keypoints first, then the normals SHOT reads around them.
    std::optional<NormalEstimator> normals;
    {
      ScopedStage stage(timings, "keypoints");
      normals.emplace(*points, params.normals, scene.sensor_origin);
      keypoints = detectContourKeypoints(scene, *normals, params.keypoints, params.downsample.leaf_size);
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
    result.features = describe(*result.surface, keypoints, params.shot);
  }
  return result;
}

}  // namespace ism
