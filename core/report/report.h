#pragma once
// Presenting a recognition result: a text table, JSON, a picture of the scene from the sensor's
// viewpoint with the hypotheses' boxes drawn, and a PLY of keypoints and votes for debugging.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/recognition/recognizer.h"

namespace ism {

// Fixed-width table: category, score, threshold, centre, box size, support (best first).
// Rejected hypotheses (failed box selection) are listed after the accepted ones when asked.
std::string hypothesesTable(const RecognitionResult& result, bool include_rejected = false);

nlohmann::json toJson(const Hypothesis& hypothesis);
// {"hypotheses": [...], "rejected": [...], "timings_ms": [{"stage", "ms"}...], "input_points",
//  "surface_points", "keypoints"}.
nlohmann::json toJson(const RecognitionResult& result);

// The base is the sensor the picture is taken with: Kinect intrinsics by default, placed at the
// scene's sensor pose (optical frame: x right, y down, z forward). A cloud without an image grid
// (a fused room, a point sample) has no such pose: it is seen from its sensor origin looking at
// its points' mean direction, `up` (the recognised gravity, when known) up in the picture, with
// the focal length widened until 98 % of the points are in the frame.
struct PictureParams : CameraIntrinsics {
  int line_width = 2;
  std::optional<Eigen::Vector3f> up;
};

// RGB colour of a category's boxes; stable across runs (derived from the name).
Eigen::Vector3i categoryColor(const std::string& category);

// The scene's points projected into the sensor (rgb when the scene has colour, else shaded by
// depth, nearer brighter) with every hypothesis' oriented box drawn as a projected wireframe.
// With `model`, each verified hypothesis also gets the training shape that fitted it, at its
// fitted pose, as dots in its category's colour where they are not behind the scene's surface.
// Returns PNG bytes.
std::string renderPicture(const Scene& scene, const std::vector<Hypothesis>& hypotheses,
                          const PictureParams& params = {}, const Model* model = nullptr);
void savePicture(const Scene& scene, const std::vector<Hypothesis>& hypotheses, const std::string& path,
                 const PictureParams& params = {}, const Model* model = nullptr);

// Keypoints (white), votes (in their category's colour, brighter = heavier) and hypothesis
// centres (red) as one coloured PLY. Needs a result of `model` recognised with keep_votes.
void saveDebugPly(const Model& model, const RecognitionResult& result, const std::string& path);

}  // namespace ism
