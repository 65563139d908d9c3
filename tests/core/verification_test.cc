// Verification against rendered rooms: a chair's own shape placed where the chair stands agrees
// with the depth the sensor measured; placed where the sensor sees through to a wall it does not.
#include "core/recognition/verification.h"

#include <cmath>
#include <optional>
#include <utility>

#include <gtest/gtest.h>

#include "core/common/upright_box.h"
#include "core/recognition/top_seen.h"
#include "core/scanner/scanner.h"
#include "tests/common/known_gravity.h"
#include "tests/common/synthetic_furniture.h"

namespace ism {
namespace {

using testing::knownFloor;

constexpr float kChairX = 0.3f, kChairY = 0.4f, kChairYaw = 0.7f;

struct Room {
  SyntheticScene rendered;
  CategoryModel chairs;
  Mesh chair;
};

// A chair on the floor before a wall, seen from 3 m at a person's height; the category keeps the
// chair's own shape and a table's, as a model trained on both would.
Room chairBeforeWall() {
  Room room;
  room.chair = testing::syntheticFurniture("dining_chair", 0);
  const Mesh other = testing::syntheticFurniture("dining_table", 0);
  std::vector<SceneObject> objects{{"chair", room.chair, kChairX, kChairY, kChairYaw},
                                   {"", testing::boxMesh({-3, 2.0f, 0}, {3, 2.1f, 2.5f}), 0, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.0f, -2.6f, 1.4f};
  params.camera_target = {0.2f, 0.4f, 0.4f};
  params.floor_size = 8.0f;
  room.rendered = composeScene(objects, params);
  room.chairs.name = "chair";
  for (const Mesh* mesh : {&other, static_cast<const Mesh*>(&room.chair)}) {
    TrainingObject object;
    object.size = mesh->bounds().sizes();
    object.center_height = object.size.z() / 2;
    object.surface = sampleSurface(*mesh, 0.02f, 1500);
    room.chairs.objects.push_back(object);
  }
  return room;
}

Hypothesis chairAt(const Room& room, float x, float y, float yaw) {
  UprightBox box;
  box.size = room.chair.bounds().sizes();
  box.center = {x, y, box.size.z() / 2};
  box.yaw = yaw;
  Hypothesis h;
  h.category = "chair";
  h.box = box.toScene(Eigen::Matrix3f::Identity());
  h.center = box.center;
  return h;
}

// Verification without its pose search: one heading, no steps, so that the pose stays where the
// hypothesis puts it (unless ICP moves it).
VerificationParams gridOff() {
  VerificationParams params;
  params.coarse_yaws = 1;
  params.coarse_steps = 0;
  params.refined_poses = 1;
  params.fine_yaw = 0;
  params.fine_shift = 0;
  params.icp_iterations = 0;
  return params;
}

TEST(Verification, TheChairsOwnShapeFitsWhereItStands) {
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  // Voting's centre is off by a few centimetres and its heading by a few degrees.
  const auto fit = verify(scene, room.chairs, chairAt(room, kChairX + 0.06f, kChairY - 0.05f, kChairYaw + 0.2f));
  ASSERT_TRUE(fit.has_value());
  EXPECT_EQ(fit->object, 1) << "the chair's shape, not the table's";
  EXPECT_GT(fit->fit(), 0.8f) << fit->consistent << " of " << fit->seen;
  EXPECT_GT(fit->seen, 100);
  const Eigen::Vector3f truth(kChairX, kChairY, room.chair.bounds().sizes().z() / 2);
  EXPECT_LT((fit->center - truth).head<2>().norm(), 0.05f);
  EXPECT_LT(std::abs(std::remainder(fit->yaw - kChairYaw, 2 * static_cast<float>(M_PI))), 0.2f);
}

TEST(Verification, RankingPosesOnFewerPointsFindsTheSamePose) {
  // The refinement ranks its poses on ranking_points of each shape's points and scores only the
  // best on max_points: on a clean view the cheap ranking picks the pose the full one does, and
  // the reported counts are the full pose's.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const Hypothesis start = chairAt(room, kChairX + 0.06f, kChairY - 0.05f, kChairYaw + 0.2f);
  VerificationParams full;
  full.ranking_points = full.max_points;
  VerificationParams cheap;
  cheap.ranking_points = 200;
  const auto a = verify(scene, room.chairs, start, full);
  const auto b = verify(scene, room.chairs, start, cheap);
  ASSERT_TRUE(a.has_value() && b.has_value());
  EXPECT_EQ(a->object, b->object);
  EXPECT_FLOAT_EQ(a->yaw, b->yaw);
  EXPECT_LT((a->center - b->center).norm(), 1e-4f);
  EXPECT_EQ(a->seen, b->seen);
  EXPECT_EQ(a->consistent, b->consistent);
  EXPECT_GT(b->seen, cheap.ranking_points) << "counted over max_points, not ranking_points";
}

// The chair's verification from 9 cm and 0.3 rad off, without the pose search: before and after
// 10 steps of ICP.
std::pair<std::optional<Verification>, std::optional<Verification>> icpFromOffset(const VerificationScene& scene,
                                                                                  const Room& room) {
  const Hypothesis start = chairAt(room, kChairX + 0.07f, kChairY - 0.06f, kChairYaw + 0.3f);
  VerificationParams icp = gridOff();
  icp.icp_iterations = 10;
  return {verify(scene, room.chairs, start, gridOff()), verify(scene, room.chairs, start, icp)};
}

TEST(Verification, IcpBringsTheShapeOntoTheChair) {
  // The grid switched off (one heading, no steps): the pose stays where voting put it, 9 cm and
  // 0.3 rad off; ICP moves it onto the chair, and the chair then explains more of the shape.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const auto [before, after] = icpFromOffset(scene, room);
  ASSERT_TRUE(before.has_value() && after.has_value());
  ASSERT_EQ(after->object, before->object);
  const Eigen::Vector2f truth(kChairX, kChairY);
  const auto yaw_error = [](const Verification& v) { return std::abs(std::remainder(v.yaw - kChairYaw, 2 * static_cast<float>(M_PI))); };
  EXPECT_GT((before->center.head<2>() - truth).norm(), 0.08f);
  EXPECT_LT((after->center.head<2>() - truth).norm(), 0.03f);
  EXPECT_LT(yaw_error(*after), 0.1f);
  EXPECT_GT(after->fit(), before->fit() + 0.1f) << after->consistent << " of " << after->seen << " against "
                                                << before->consistent << " of " << before->seen;
}

TEST(Verification, ShapesWhereTheSensorSeesTheWallAreSeenThrough) {
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const auto fit = verify(scene, room.chairs, chairAt(room, -1.2f, 0.8f, 0.0f));
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(fit->fit(), 0.3f) << fit->consistent << " of " << fit->seen;
  EXPECT_GT(fit->seen, 50);
}

// A bench 1.4 m long with its seat at 0.45 m before the wall, where voting would put a chair: the
// chair's shape fits its seat and legs, but the sensor sees the wall through its backrest. On the
// chair itself the backrest is measured. A single view only, and switched off it is kept.
TEST(Verification, TheFittedShapesTopPartIsScoredApart) {
  const Room room = chairBeforeWall();
  std::vector<SceneObject> objects{{"", testing::boxMesh({-0.7f, -0.2f, 0}, {0.7f, 0.2f, 0.45f}), -1.0f, 0.6f, 0},
                                   {"", testing::boxMesh({-3, 2.0f, 0}, {3, 2.1f, 2.5f}), 0, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.0f, -2.6f, 1.4f};
  params.camera_target = {0.2f, 0.4f, 0.4f};
  params.floor_size = 8.0f;
  const SyntheticScene bench_room = composeScene(objects, params);
  const VerificationScene bench_view = makeVerificationScene(bench_room.scene, knownFloor());
  Hypothesis on_bench = chairAt(room, -1.0f, 0.6f, 0.0f);
  on_bench.verification = verify(bench_view, room.chairs, on_bench);
  ASSERT_TRUE(on_bench.verification.has_value());
  const TopSeenCheck bench = checkTopSeen(bench_view, on_bench);
  EXPECT_GT(bench.seen, 20) << "the wall measured behind the backrest";
  EXPECT_LT(bench.share(), 0.05f) << bench.consistent << " of " << bench.seen;
  EXPECT_TRUE(bench.seenThrough());
  TopSeenParams off;
  off.enabled = false;
  EXPECT_FALSE(checkTopSeen(bench_view, on_bench, off).seenThrough());
  VerificationParams unscored;
  unscored.top_part = 0;
  const auto whole_only = verify(bench_view, room.chairs, on_bench, unscored);
  ASSERT_TRUE(whole_only.has_value());
  EXPECT_EQ(whole_only->top_seen, 0) << "the top part not scored";
  EXPECT_EQ(whole_only->seen, on_bench.verification->seen) << "the whole shape's fit as before";

  const VerificationScene view = makeVerificationScene(room.rendered.scene, knownFloor());
  Hypothesis on_chair = chairAt(room, kChairX + 0.06f, kChairY - 0.05f, kChairYaw + 0.2f);
  on_chair.verification = verify(view, room.chairs, on_chair);
  ASSERT_TRUE(on_chair.verification.has_value());
  const TopSeenCheck chair = checkTopSeen(view, on_chair);
  EXPECT_GT(chair.seen, 20);
  EXPECT_GT(chair.share(), 0.5f) << "the backrest itself";
  EXPECT_FALSE(chair.seenThrough());

  VerificationScene as_map = bench_view;  // a map's sparse samples and made-up viewpoint
  as_map.map = true;
  EXPECT_FALSE(checkTopSeen(as_map, on_bench).looked);
}

TEST(Verification, ThePartsAChairHidesSayNothing) {
  // A chair standing right behind the real one, from the sensor: most of it is hidden, so it is
  // neither confirmed nor refuted by what is hidden.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const auto behind = verify(scene, room.chairs, chairAt(room, kChairX + 0.05f, kChairY + 1.0f, kChairYaw));
  const auto open = verify(scene, room.chairs, chairAt(room, -1.2f, 0.8f, 0.0f));
  ASSERT_TRUE(behind.has_value() && open.has_value());
  EXPECT_LT(behind->seen, open->seen);
}

TEST(Verification, EachTermWeighsWhatTheSensorSawThroughOrNot) {
  // Without free space, hidden pixels count against a shape as seen-through ones do; without
  // inliers, they count for it as agreeing ones do. Where the sensor sees through the shape to
  // the wall, every weighing finds it wrong. The pose search is off, so that each weighing
  // judges the same pose.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const auto fitWith = [&](FitTerms terms, const Hypothesis& h) {
    VerificationParams params = gridOff();
    params.fit_terms = terms;
    const auto v = verify(scene, room.chairs, h, params);
    EXPECT_TRUE(v.has_value());
    return v ? v->fit() : 0.0f;
  };
  const Hypothesis behind = chairAt(room, kChairX + 0.05f, kChairY + 1.0f, kChairYaw);
  const float both = fitWith(FitTerms::kBoth, behind);
  EXPECT_LT(fitWith(FitTerms::kInliers, behind), 0.5f * both);
  EXPECT_GT(fitWith(FitTerms::kFreeSpace, behind), both + 0.3f);
  const Hypothesis open = chairAt(room, -1.2f, 0.8f, 0.0f);
  for (const FitTerms terms : {FitTerms::kBoth, FitTerms::kInliers, FitTerms::kFreeSpace}) {
    EXPECT_LT(fitWith(terms, open), 0.3f) << static_cast<int>(terms);
  }
}

TEST(Verification, ASecondHypothesisOnTheSameChairIsItsDuplicate) {
  const Room room = chairBeforeWall();
  Model model;
  model.categories.push_back(room.chairs);
  std::vector<Hypothesis> hypotheses{chairAt(room, kChairX, kChairY, kChairYaw),
                                     chairAt(room, kChairX - 0.3f, kChairY + 0.25f, kChairYaw)};
  hypotheses[0].confidence = 0.9f;
  hypotheses[1].confidence = 0.4f;
  std::swap(hypotheses[0], hypotheses[1]);  // verified most confident first, whatever the order
  verifyHypotheses(makeVerificationScene(room.rendered.scene, knownFloor()), model, hypotheses);
  ASSERT_TRUE(hypotheses[0].verification && hypotheses[1].verification);
  EXPECT_EQ(hypotheses[0].confidence, 0.9f);
  EXPECT_FALSE(hypotheses[0].verification->duplicate());
  EXPECT_EQ(hypotheses[0].verification->claimed, 0);
  EXPECT_TRUE(hypotheses[1].verification->duplicate())
      << hypotheses[1].verification->claimed << " claimed, " << hypotheses[1].verification->consistent << " own";
}

TEST(Verification, WithoutTheFloorTheBoxBottomStandsIn) {
  const Room room = chairBeforeWall();
  Gravity no_floor = knownFloor();
  no_floor.floor_level.reset();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, no_floor);
  const auto fit = verify(scene, room.chairs, chairAt(room, kChairX, kChairY, kChairYaw));
  ASSERT_TRUE(fit.has_value());
  EXPECT_GT(fit->fit(), 0.85f);
}

TEST(Verification, NothingToSayFromInsideOrWithoutShapes) {
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  const Eigen::Vector3f eye = room.rendered.scene.sensor_origin;
  EXPECT_FALSE(verify(scene, room.chairs, chairAt(room, eye.x(), eye.y(), 0)).has_value()) << "the sensor inside";
  CategoryModel bare = room.chairs;
  for (auto& o : bare.objects) o.surface.clear();
  EXPECT_FALSE(hasShapes(bare));
  EXPECT_FALSE(verify(scene, bare, chairAt(room, kChairX, kChairY, kChairYaw)).has_value());
}

TEST(Verification, ShapesHeldOutAreNotTried) {
  // Calibration clears the shapes of the objects its rooms show, as the world shows none of them:
  // the chair's own shape held out, only the table's is left to fit, and it fits worse.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(room.rendered.scene, knownFloor());
  CategoryModel held_out = room.chairs;
  held_out.objects[1].surface.clear();
  EXPECT_TRUE(hasShapes(held_out));
  const Hypothesis chair = chairAt(room, kChairX, kChairY, kChairYaw);
  const auto own = verify(scene, room.chairs, chair);
  const auto other = verify(scene, held_out, chair);
  ASSERT_TRUE(own.has_value());
  ASSERT_TRUE(other.has_value());
  EXPECT_EQ(own->object, 1);
  EXPECT_EQ(other->object, 0) << "the held-out shape was tried";
  EXPECT_LT(other->fit(), own->fit());
}

TEST(Verification, VerifiedHypothesesGetTheFittedShapesBox) {
  const Room room = chairBeforeWall();
  Model model;
  model.categories.push_back(room.chairs);
  std::vector<Hypothesis> hypotheses{chairAt(room, kChairX + 0.06f, kChairY, kChairYaw), chairAt(room, -1.2f, 0.8f, 0)};
  hypotheses[1].category = "unknown";  // a category the model does not have is left alone
  const OrientedBox before = hypotheses[1].box;
  verifyHypotheses(makeVerificationScene(room.rendered.scene, knownFloor()), model, hypotheses);
  ASSERT_TRUE(hypotheses[0].verification.has_value());
  EXPECT_LT((hypotheses[0].box.center - Eigen::Vector3f(kChairX, kChairY, hypotheses[0].box.center.z())).norm(), 0.05f);
  EXPECT_NEAR(hypotheses[0].box.center.z(), room.chair.bounds().sizes().z() / 2, 1e-4f);
  EXPECT_FALSE(hypotheses[1].verification.has_value());
  EXPECT_EQ(hypotheses[1].box.center, before.center);
}

// The room of chairBeforeWall() fused from four cameras around it into one cloud without image
// grid, looked at from its middle at eye height as recognition looks at a map (viewpoint.h).
Scene fusedRoom(const Room& room) {
  std::vector<SceneObject> objects{{"chair", room.chair, kChairX, kChairY, kChairYaw},
                                   {"", testing::boxMesh({-3, 2.0f, 0}, {3, 2.1f, 2.5f}), 0, 0, 0}};
  Scene map;
  map.sensor_origin = {0.0f, 0.0f, 1.5f};
  for (const Eigen::Vector3f& eye : {Eigen::Vector3f(0.0f, -2.6f, 1.4f), Eigen::Vector3f(2.4f, 0.2f, 1.4f),
                                     Eigen::Vector3f(-2.4f, 0.2f, 1.4f), Eigen::Vector3f(0.0f, 1.8f, 1.6f)}) {
    SyntheticSceneParams params;
    params.camera_eye = eye;
    params.camera_target = {kChairX, kChairY, 0.4f};
    params.floor_size = 8.0f;
    const SyntheticScene view = composeScene(objects, params);
    for (size_t i = 0; i < view.scene.cloud->size(); i += 4) map.cloud->push_back((*view.scene.cloud)[i]);
  }
  return map;
}

TEST(Verification, AMapIsCheckedInThreeDimensions) {
  const Room room = chairBeforeWall();
  const Scene map = fusedRoom(room);
  const VerificationScene scene = makeVerificationScene(map, knownFloor());
  EXPECT_TRUE(scene.map);
  // A single view stays on its depth buffer, with or without its image grid.
  EXPECT_FALSE(makeVerificationScene(room.rendered.scene, knownFloor()).map);
  Scene unorganized = room.rendered.scene;
  unorganized.image_width = unorganized.image_height = 0;
  EXPECT_FALSE(makeVerificationScene(unorganized, knownFloor()).map);
  VerificationParams viewpoint;
  viewpoint.maps_in_3d = false;
  EXPECT_FALSE(makeVerificationScene(map, knownFloor(), viewpoint).map);

  const auto fit = verify(scene, room.chairs, chairAt(room, kChairX + 0.06f, kChairY - 0.05f, kChairYaw + 0.2f));
  ASSERT_TRUE(fit.has_value());
  EXPECT_EQ(fit->object, 1) << "the chair's shape, not the table's";
  EXPECT_GT(fit->fit(), 0.6f) << fit->consistent << " of " << fit->seen;
  EXPECT_LT((fit->center.head<2>() - Eigen::Vector2f(kChairX, kChairY)).norm(), 0.06f);
  EXPECT_EQ(fit->top_seen, 0) << "a map's top part is not scored: top_seen.h reads single views";
  // Against the wall, the shape's parts that stand out from it have no measured point near them;
  // in the open, none has.
  const auto wall = verify(scene, room.chairs, chairAt(room, -1.5f, 1.75f, 0.0f));
  const auto open = verify(scene, room.chairs, chairAt(room, -1.5f, -1.0f, 0.0f));
  ASSERT_TRUE(wall.has_value() && open.has_value());
  EXPECT_LT(wall->fit(), fit->fit() - 0.2f) << wall->consistent << " of " << wall->seen;
  EXPECT_LT(open->fit(), 0.1f) << open->consistent << " of " << open->seen;
}

TEST(Verification, IcpAlignsInAMapToo) {
  // In a map every shape point above the floor pairs with its nearest measured point.
  const Room room = chairBeforeWall();
  const VerificationScene scene = makeVerificationScene(fusedRoom(room), knownFloor());
  ASSERT_TRUE(scene.map);
  const auto [before, after] = icpFromOffset(scene, room);
  ASSERT_TRUE(before.has_value() && after.has_value());
  const Eigen::Vector2f truth(kChairX, kChairY);
  EXPECT_LT((after->center.head<2>() - truth).norm(), 0.5f * (before->center.head<2>() - truth).norm());
  EXPECT_GT(after->fit(), before->fit());
}

TEST(Verification, AMapsHypothesisAtItsViewpointIsChecked) {
  // The viewpoint a map is given stands in the middle of the room, here in the chair: a depth
  // buffer from there cannot look at the chair, the 3D check can.
  const Room room = chairBeforeWall();
  Scene map = fusedRoom(room);
  map.sensor_origin = {kChairX, kChairY, 0.5f};
  const Hypothesis chair = chairAt(room, kChairX, kChairY, kChairYaw);
  const auto fit = verify(makeVerificationScene(map, knownFloor()), room.chairs, chair);
  ASSERT_TRUE(fit.has_value());
  EXPECT_GT(fit->fit(), 0.6f);
  VerificationParams viewpoint;
  viewpoint.maps_in_3d = false;
  EXPECT_FALSE(verify(makeVerificationScene(map, knownFloor(), viewpoint), room.chairs, chair, viewpoint).has_value());
}

}  // namespace
}  // namespace ism

namespace ism {
namespace {

TEST(ShapeProfile, SharesOverHeightAndRingsOfTheBox) {
  const Eigen::Vector3f size(1.0f, 0.5f, 1.0f);
  // Two points in the axis' ring at a twentieth of the height, one on the box's edge near the top,
  // one past the edge and above the box (counted in the outermost ring and the highest bin).
  const ShapeProfile p = shapeProfile({{0.0f, 0.0f, 0.05f}, {0.1f, 0.02f, 0.05f}, {0.49f, 0.0f, 0.95f}, {0.7f, 0.3f, 2.0f}},
                                      size);
  EXPECT_EQ(p.points, 4);
  EXPECT_FLOAT_EQ(p.share[0 * ShapeProfile::kRings + 0], 0.5f);
  EXPECT_FLOAT_EQ(p.share[9 * ShapeProfile::kRings + 3], 0.25f);
  EXPECT_FLOAT_EQ(p.share[11 * ShapeProfile::kRings + 3], 0.25f);
  EXPECT_FLOAT_EQ(profileDistance(p, p), 0.0f);
  const ShapeProfile other = shapeProfile({{0.0f, 0.0f, 0.55f}}, size);
  EXPECT_FLOAT_EQ(profileDistance(p, other), 2.0f) << "no bin in common";
  EXPECT_FLOAT_EQ(profileDistance(p, other), profileDistance(other, p));
}

TEST(ShapeProfile, AChairsSurfaceIsNearerAChairsThanACabinetsIs) {
  // The chair before the wall, and a cabinet (a closed box of a chair's width and depth, a little
  // taller) standing apart: the chair's verification finds the measured surface shaped as its
  // training shape, the cabinet's finds it spread over its whole front.
  const Room reference = chairBeforeWall();
  const Mesh cabinet = testing::boxMesh({-0.25f, -0.25f, 0.0f}, {0.25f, 0.25f, 1.0f});
  std::vector<SceneObject> objects{{"chair", reference.chair, kChairX, kChairY, kChairYaw},
                                   {"", cabinet, -1.2f, 0.6f, 0.0f},
                                   {"", testing::boxMesh({-3, 2.0f, 0}, {3, 2.1f, 2.5f}), 0, 0, 0}};
  SyntheticSceneParams params;
  params.camera_eye = {0.0f, -2.6f, 1.4f};
  params.camera_target = {-0.4f, 0.4f, 0.4f};
  params.floor_size = 8.0f;
  const SyntheticScene rendered = composeScene(objects, params);
  const VerificationScene scene = makeVerificationScene(rendered.scene, knownFloor());
  const auto on_chair = verify(scene, reference.chairs, chairAt(reference, kChairX, kChairY, kChairYaw));
  const auto on_cabinet = verify(scene, reference.chairs, chairAt(reference, -1.2f, 0.6f, 0.0f));
  ASSERT_TRUE(on_chair.has_value() && on_cabinet.has_value());
  EXPECT_LT(on_chair->profile_distance, 0.5f * on_cabinet->profile_distance)
      << on_chair->profile_distance << " against " << on_cabinet->profile_distance;
}

}  // namespace
}  // namespace ism
