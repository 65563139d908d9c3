#pragma once
// The up direction of a scene, its floor, and the large planes (floor, walls) that are never
// keypoints. Furniture stands on the floor, upright: once up and the floor are known, a
// keypoint's height above the floor and the heading of its surface about up are what votes are
// cast with (recognition), and floor and walls, which look alike in every room and carry no
// furniture, stop voting at all.
//
// Up comes from the caller when it knows it (a robot's TF, an accelerometer, a gravity-levelled
// room scan), checked against the floor (GravityParams::given_up_kept_deg); otherwise it is the
// normal of the floor, found by RANSAC among planes near the
// sensor's own up (the optical frame's -y) with almost no points below them. A scene without a
// visible floor keeps the sensor's up and has no floor: heights are then unknown.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/common/gravity_frame.h"

namespace ism {

struct GravityParams {
  // Find up, the floor and walls, and keep keypoints off floor and walls. Off in the seed's
  // pipeline, which knows nothing of gravity.
  bool enabled = true;
  // Estimated up: the floor's normal lies within this angle of the sensor's up.
  float max_tilt_deg = 45.0f;
  // Given up: the floor is searched among planes within this angle of it.
  float given_up_tolerance_deg = 10.0f;
  // A given up is kept unless the floor among those planes holds more points than the plane square
  // to it and its normal lies more than this (deg) from it: then the caller's frame is tilted and
  // the floor's normal is up (source kFloor). A levelled robot's accelerometer and a room scan's
  // alignment are good to a degree or two, and a single frame's floor fitted through the Kinect's
  // depth distortion is off by as much (SUN RGB-D's given z is 0.8-2 deg off its frames' floor
  // planes), so only a larger tilt is taken to be the caller's; a map aligned 7 deg off (one of
  // ScanNet's) holds no floor square to its z at all. given_up_tolerance_deg or more: the given up
  // is never second-guessed (ism-detect, ism-eval --trust-given-up). docs/EVALUATION.md, "A given
  // up checked against the floor".
  float given_up_kept_deg = 3.0f;
  // A point within this distance of a plane supports it (m) when planes are searched. Points are
  // labelled as on a plane within the larger of this and noise_sigmas times the sensor's depth
  // noise at their range (NoiseParams' Kinect model: 2.6 cm at 4 m).
  float inlier_distance = 0.03f;
  float noise_sigmas = 2.5f;
  // The floor carries at least this fraction of the scene's points ...
  float min_floor_fraction = 0.03f;
  // ... and has at most this fraction more than `below_margin` under it (reconstructions and
  // noisy frames put a few stray points below the floor; a table top has the floor below it).
  float max_below_fraction = 0.02f;
  float below_margin = 0.08f;
  // A wall is a plane within wall_tilt_deg of vertical whose supporting points span at least
  // this much in height and along the floor. A couch is as wide but lower, an office chair's back
  // as high but narrower: no face of the seed's categories is taken for a wall. A camera looking
  // down sees a wall's lowest metre or so.
  float wall_min_height = 1.0f;
  float wall_min_width = 1.5f;
  float wall_tilt_deg = 10.0f;
  // Walls as connected surfaces (gravity.cc, connectedWall): the points on a wall's plane joined
  // through cells of this size (m) along the floor and up, where they are dense enough to show a
  // surface, and only the pieces so joined are the wall's. 0: every point on the plane within its
  // points' extent is the wall's, even where that plane only cuts through furniture (a chair's
  // back, a desk's front and a shelf's side that happen to line up). Optional (ism-train
  // --wall-cell 0.15): it gave tum_desk's desk and chairs twice their keypoints and confidence, but
  // lost 3-6 points of the dev clouds' mAP (docs/EVALUATION.md, "Walls as connected surfaces").
  float wall_cell = 0.0f;
  // A wall bounds the room and is opaque: a plane with more than this many points (as a fraction
  // of its own) seen through it - behind it, where its own points leave a gap - is no wall
  // (gravity.cc, seenThrough). 0: not looked at, every plane of a wall's size is one. Only a
  // scene with a sensor is tested: a map's viewpoint is made up (frontend.cc). The shipped model
  // is trained with 1 (ism-train --wall-seen-through 1): the Kinect frames' furniture that lines
  // up with a plane gets 2-4x its confidence, and the dev clouds move within the draws' spread.
  // The freed planes' keypoints cost a frame 1.6x, so the shipped model holds two draws: three
  // would take a Kinect frame too near 100 ms on one core (docs/EVALUATION.md, "Walls the room is
  // seen through").
  float wall_max_seen_through = 0.0f;
  int max_walls = 6;
  int iterations = 300;          // RANSAC hypotheses per plane
  int prior_iterations = 64;     // and planes square to the sensor's up when up is not given
  size_t sample_points = 20000;  // planes are scored on this many points spread over the scene
  uint32_t seed = 1;             // the same scene always gives the same planes
};

// Per point of a cloud: what large plane it lies on.
enum class PlaneLabel : uint8_t { kNone = 0, kFloor = 1, kWall = 2 };

struct GravityResult {
  Gravity gravity;
  std::vector<PlaneLabel> labels;  // per point of the cloud given
};

// `points` are the scene's (downsampled) points. `sensor_origin` is where the sensor was and
// `sensor_up` its up, both in scene coordinates (its orientation applied to the optical frame's
// -y); `given_up` the caller's. Throws Error(kInvalidInput) when given_up is not a finite,
// non-zero vector.
GravityResult estimateGravity(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& sensor_origin,
                              const Eigen::Vector3f& sensor_up, const std::optional<Eigen::Vector3f>& given_up,
                              const GravityParams& params = {});

}  // namespace ism
