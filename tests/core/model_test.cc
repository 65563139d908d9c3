#include "core/model/model_file.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <zlib.h>

#include "core/common/error.h"
#include "tests/common/expect_error.h"
#include "ism/v1/model.pb.h"

namespace ism {
namespace {

VoteTable randomVotes(int codewords, int votes_per_codeword) {
  VoteTable t;
  t.offsets.push_back(0);
  for (int c = 0; c < codewords; ++c) {
    for (int v = 0; v < votes_per_codeword + c % 3; ++v) t.vectors.push_back(Eigen::Vector3f::Random());
    t.offsets.push_back(static_cast<uint32_t>(t.vectors.size()));
  }
  return t;
}

Model sampleModel() {
  Model m;
  m.front_end.downsample.leaf_size = 0.012f;
  m.front_end.smoothing.enabled = false;
  m.front_end.shot.min_neighbours = 7;
  m.trained_knn.k = 2;
  m.voting = {VoteFrame::kUpright, 0.15f, true};
  m.trained_cutoff.cutoff = 0.3f;
  m.global_codebook = Codebook(DescriptorMatrix::Random(6, 352));
  for (const char* name : {"couch", "bed"}) {
    CategoryModel c;
    c.name = name;
    c.bin_size = 0.2f;
    c.box = {0.1f, 2.0f, 2.5f, 1.0f, 0.4f, 1.8f, 0.3f};
    c.own_codebook = Codebook(DescriptorMatrix::Random(4, 352));
    c.global_votes = randomVotes(6, 2);
    if (std::string(name) == "couch") c.global_votes.codeword_weights = {1.0f, 0.5f, 0.25f, 1.0f, 0.75f, 0.125f};
    c.own_votes = randomVotes(4, 1);
    c.thresholds[{CodebookType::kGlobal, ActivationStrategy::kKnn, VoteWeighting::kActivation}] = 0.75f;
    c.thresholds[{CodebookType::kSeparated, ActivationStrategy::kCutoff, VoteWeighting::kCategorization}] = 12.0f;
    c.training_models = 3;
    c.training_scans = 36;
    for (int o = 0; o < 3; ++o) {
      c.objects.push_back({Eigen::Vector3f(0.5f + o, 0.6f, 0.9f), 0.45f, {Eigen::Vector3f(0.1f * o, 0.2f, 0.3f), Eigen::Vector3f::Random()},
                           o == 1});
    }
    Calibration calibration;
    calibration.a = 1.5f;
    calibration.b = -2.0f;
    calibration.c = 0.25f;
    calibration.d = 3.5f;
    calibration.e = -1.75f;
    calibration.min_score = 0.01f;
    calibration.positives = 40;
    calibration.negatives = 400;
    c.calibration = calibration;
    if (std::string(name) == "couch") {  // one category calibrated for clouds too, one not
      calibration.b = -4.0f;
      c.cloud_calibration = calibration;
    }
    m.categories.push_back(c);
  }
  m.provenance = {{"couch\ta.obj\tme", "bed\tb.obj\tyou"}, 72, "2024-01-01T00:00:00Z", "v1-test", "ism-train ..."};
  return m;
}

void expectEqual(const VoteTable& a, const VoteTable& b) {
  EXPECT_EQ(a.offsets, b.offsets);
  ASSERT_EQ(a.vectors.size(), b.vectors.size());
  for (size_t i = 0; i < a.vectors.size(); ++i) EXPECT_EQ(a.vectors[i], b.vectors[i]);
}

class ModelFileTest : public ::testing::Test {
 protected:
  std::string path = ::testing::TempDir() + "/model_test_" +
                     ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".ism";
  void TearDown() override { std::remove(path.c_str()); }

  void writeBytes(const std::string& bytes) {
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  void expectCorrupt(const std::string& bytes, const std::string& check) {
    writeBytes(bytes);
    try {
      loadModel(path);
      FAIL() << "loaded a model that should fail the " << check << " check";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kCorruptModel) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(check), std::string::npos) << e.what();
    }
  }
};

TEST_F(ModelFileTest, RoundTripKeepsEveryField) {
  const Model m = sampleModel();
  saveModel(m, path);
  const Model r = loadModel(path);
  EXPECT_EQ(r.front_end.downsample.leaf_size, 0.012f);
  EXPECT_FALSE(r.front_end.smoothing.enabled);
  EXPECT_EQ(r.front_end.shot.min_neighbours, 7);
  EXPECT_EQ(r.front_end.keypoints.angle_threshold, m.front_end.keypoints.angle_threshold);
  EXPECT_EQ(r.trained_knn.k, 2);
  EXPECT_EQ(r.voting.frame, VoteFrame::kUpright);
  EXPECT_EQ(r.voting.height_tolerance, 0.15f);
  EXPECT_TRUE(r.voting.height_normalized);
  EXPECT_EQ(r.trained_cutoff.strategy, ActivationStrategy::kCutoff);
  EXPECT_EQ(r.trained_cutoff.cutoff, 0.3f);
  ASSERT_TRUE(r.global_codebook);
  EXPECT_EQ(r.global_codebook->centers(), m.global_codebook->centers());
  ASSERT_EQ(r.categories.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const auto &a = m.categories[i], &b = r.categories[i];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.bin_size, b.bin_size);
    EXPECT_EQ(a.box.max_edge, b.box.max_edge);
    EXPECT_EQ(a.box.std_max_edge, b.box.std_max_edge);
    ASSERT_TRUE(b.own_codebook);
    EXPECT_EQ(a.own_codebook->centers(), b.own_codebook->centers());
    expectEqual(a.global_votes, b.global_votes);
    EXPECT_EQ(a.global_votes.codeword_weights, b.global_votes.codeword_weights);
    expectEqual(a.own_votes, b.own_votes);
    EXPECT_EQ(a.thresholds, b.thresholds);
    EXPECT_EQ(b.training_models, 3);
    EXPECT_EQ(b.training_scans, 36);
    ASSERT_EQ(b.objects.size(), a.objects.size());
    for (size_t o = 0; o < a.objects.size(); ++o) {
      EXPECT_EQ(b.objects[o].size, a.objects[o].size);
      EXPECT_EQ(b.objects[o].center_height, a.objects[o].center_height);
      EXPECT_EQ(b.objects[o].surface, a.objects[o].surface);
      EXPECT_EQ(b.objects[o].size_guessed, a.objects[o].size_guessed);
    }
    ASSERT_TRUE(b.calibration);
    EXPECT_EQ(b.calibration->d, 3.5f);
    EXPECT_EQ(b.calibration->e, -1.75f);
    EXPECT_EQ(b.calibration->confidence(2.0f, 5, 0.8f, 0.3f), a.calibration->confidence(2.0f, 5, 0.8f, 0.3f));
    ASSERT_EQ(b.cloud_calibration.has_value(), a.cloud_calibration.has_value()) << a.name;
    if (a.cloud_calibration) EXPECT_EQ(b.cloud_calibration->b, -4.0f);
  }
  EXPECT_EQ(r.provenance.meshes, m.provenance.meshes);
  EXPECT_EQ(r.provenance.scans, 72);
  EXPECT_EQ(r.provenance.created, m.provenance.created);
  EXPECT_EQ(r.provenance.code_version, "v1-test");
  EXPECT_EQ(r.provenance.command, m.provenance.command);
  EXPECT_TRUE(r.has(CodebookType::kGlobal));
  EXPECT_TRUE(r.has(CodebookType::kSeparated));
}

TEST_F(ModelFileTest, RejectsACorruptedByte) {
  std::string bytes = serializeModel(sampleModel());
  bytes[bytes.size() / 2] ^= 0x10;  // inside the payload, the bulk of the file
  expectCorrupt(bytes, "CRC-32");
}

TEST_F(ModelFileTest, RejectsATruncatedFile) {
  const std::string bytes = serializeModel(sampleModel());
  expectCorrupt(bytes.substr(0, bytes.size() - 100), "truncated");
}

TEST_F(ModelFileTest, RejectsWrongMagic) {
  v1::ModelFile file;
  file.ParseFromString(serializeModel(sampleModel()));
  file.set_magic("NOT-A-MODEL");
  expectCorrupt(file.SerializeAsString(), "wrong magic");
}

TEST_F(ModelFileTest, RejectsANewerFormatVersion) {
  v1::ModelFile file;
  file.ParseFromString(serializeModel(sampleModel()));
  file.set_format_version(kModelFormatVersion + 1);
  expectCorrupt(file.SerializeAsString(), "format version 2");
}

// The sample model's file with its payload changed by `edit` and a valid checksum, so that the
// loader's consistency checks, not the CRC, must catch the change.
template <class Edit>
std::string editedModelFile(Edit edit) {
  v1::ModelFile file;
  file.ParseFromString(serializeModel(sampleModel()));
  v1::ModelData data;
  data.ParseFromString(file.payload());
  edit(data);
  file.set_payload(data.SerializeAsString());
  file.set_payload_crc32(static_cast<uint32_t>(
      ::crc32(0L, reinterpret_cast<const Bytef*>(file.payload().data()), static_cast<uInt>(file.payload().size()))));
  return file.SerializeAsString();
}

TEST_F(ModelFileTest, RejectsInconsistentVoteTable) {
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  data.mutable_categories(1)->mutable_global_votes()->mutable_offsets()->RemoveLast();
                }),
                "category 'bed' global votes has 6 offsets");
}

TEST_F(ModelFileTest, RejectsCodewordWeightsOfAnotherCodebookOrOutsideTheRange) {
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  data.mutable_categories(0)->mutable_global_votes()->mutable_codeword_weights()->RemoveLast();
                }),
                "category 'couch' global votes has 5 codeword weights for 6 codewords");
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  data.mutable_categories(0)->mutable_global_votes()->set_codeword_weights(1, 0.0f);
                }),
                "category 'couch' global votes has a codeword weight outside (0, 1]");
}

// Found by tests/fuzz: with dim 0, size x dim matches an empty centre list for any size.
TEST_F(ModelFileTest, RejectsACodebookWithoutDimension) {
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  auto* codebook = data.mutable_global_codebook();
                  codebook->set_dim(0);
                  codebook->set_size(4000000000u);
                  codebook->clear_centers();
                }),
                "global codebook has size 4000000000 and dim 0; both must be positive");
}

TEST_F(ModelFileTest, DrawsRoundTripAndMustMatchTheFirstModel) {
  Model m = sampleModel();
  Model other = sampleModel();
  other.categories[0].calibration->b = -9.0f;  // another draw: another calibration
  m.draws = {other, other};
  saveModel(m, path);
  const Model r = loadModel(path);
  ASSERT_EQ(r.draws.size(), 2u);
  EXPECT_EQ(r.draws[1].categories[0].calibration->b, -9.0f);
  expectEqual(r.draws[1].categories[1].global_votes, other.categories[1].global_votes);
  EXPECT_TRUE(r.draws[0].draws.empty());

  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  v1::ModelData draw = data;
                  draw.mutable_categories(1)->set_name("wardrobe");
                  *data.add_draws() = draw;
                }),
                "draw 2 has other categories than the first");
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  v1::ModelData draw = data;
                  draw.mutable_front_end()->set_shot_radius(0.5f);
                  *data.add_draws() = draw;
                }),
                "draw 2 has another front end than the first");
  expectCorrupt(editedModelFile([](v1::ModelData& data) {
                  const v1::ModelData plain = data;
                  v1::ModelData drawn = data;
                  *drawn.add_draws() = plain;
                  *data.add_draws() = plain;
                  *data.add_draws() = drawn;
                }),
                "draw 3 has draws of its own");
}

TEST_F(ModelFileTest, MissingFileIsNotFound) {
  try {
    loadModel(path + ".absent");
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(e.what()).find(".absent"), std::string::npos);
  }
}

using testing::expectError;

Model modelWithOneCategory() {
  Model model;
  CategoryModel chair;
  chair.name = "chair";
  chair.bin_size = 0.1f;
  model.categories.push_back(chair);
  return model;
}

TEST(ModelFile, TheWallOptionsRoundTripAndOldFilesHaveNone) {
  EXPECT_EQ(GravityParams{}.wall_cell, 0.0f) << "off unless trained with it";
  EXPECT_EQ(GravityParams{}.wall_max_seen_through, 0.0f) << "off unless trained with it";
  for (float GravityParams::*field : {&GravityParams::wall_cell, &GravityParams::wall_max_seen_through}) {
    Model model = modelWithOneCategory();
    // A file written before the field existed holds nothing for it, as one of 0 does: off.
    model.front_end.gravity.*field = 0.0f;
    EXPECT_EQ(parseModel(serializeModel(model), "old.ismm").front_end.gravity.*field, 0.0f);
    model.front_end.gravity.*field = 0.15f;
    EXPECT_EQ(parseModel(serializeModel(model), "new.ismm").front_end.gravity.*field, 0.15f);
    model.front_end.gravity.*field = -0.15f;
    expectError([&] { parseModel(serializeModel(model), "broken.ismm"); }, ErrorCode::kCorruptModel,
                "front-end gravity parameters are out of range");
  }
}

TEST(ModelFile, TheGivenUpsCheckRoundTripsAndOldFilesHaveTheDefault) {
  Model model = modelWithOneCategory();
  model.front_end.gravity.given_up_kept_deg = 10.0f;
  EXPECT_EQ(parseModel(serializeModel(model), "new.ismm").front_end.gravity.given_up_kept_deg, 10.0f);
  // A file written before the field existed holds nothing for it: the default check applies.
  const std::string old_file = editedModelFile([](v1::ModelData& data) {
    ASSERT_TRUE(data.front_end().gravity().has_given_up_kept_deg());
    data.mutable_front_end()->mutable_gravity()->clear_given_up_kept_deg();
  });
  EXPECT_EQ(parseModel(old_file, "old.ismm").front_end.gravity.given_up_kept_deg, GravityParams{}.given_up_kept_deg);
  model.front_end.gravity.given_up_kept_deg = -1.0f;
  expectError([&] { parseModel(serializeModel(model), "broken.ismm"); }, ErrorCode::kCorruptModel,
              "front-end gravity parameters are out of range");
  // Trusted in the model and its draws alike, so that they still make one ensemble.
  model.front_end.gravity.given_up_kept_deg = 3.0f;
  model.draws.push_back(model);
  model.trustGivenUp();
  EXPECT_GE(model.front_end.gravity.given_up_kept_deg, model.front_end.gravity.given_up_tolerance_deg);
  EXPECT_TRUE(sameFrontEnd(model, model.draws[0]));
  EXPECT_EQ(parseModel(serializeModel(model), "trusted.ismm").draws.size(), 1u);
}

TEST(ModelFile, KeypointParametersRoundTripAndOldFilesLoadAsBoundary) {
  Model model = modelWithOneCategory();
  EXPECT_EQ(model.front_end.keypoints.method, KeypointMethod::kAuto) << "new models default to kAuto";
  KeypointParams& k = model.front_end.keypoints;
  k.method = KeypointMethod::kOccludingContour;
  k.contour.window = 3;
  k.contour.min_jump = 0.04f;
  k.contour.relative_jump = 0.09f;
  k.contour.max_gap = 25;
  k.min_spacing = 0.02f;
  k.surface_spacing = 0.09f;
  const std::string bytes = serializeModel(model);
  const KeypointParams loaded = parseModel(bytes, "new.ismm").front_end.keypoints;
  EXPECT_EQ(loaded.method, KeypointMethod::kOccludingContour);
  EXPECT_EQ(loaded.contour.window, 3);
  EXPECT_EQ(loaded.contour.min_jump, 0.04f);
  EXPECT_EQ(loaded.contour.relative_jump, 0.09f);
  EXPECT_EQ(loaded.contour.max_gap, 25);
  EXPECT_EQ(loaded.min_spacing, 0.02f);
  EXPECT_EQ(loaded.surface_spacing, 0.09f);
  k.surface_spacing = -0.09f;
  expectError([&] { parseModel(serializeModel(model), "broken.ismm"); }, ErrorCode::kCorruptModel,
              "keypoint_surface_spacing");
  k.surface_spacing = 0.09f;
  EXPECT_EQ(loaded.unorganized, KeypointMethod::kRangeImage) << "new models see clouds as range images";
  for (KeypointMethod method : {KeypointMethod::kAuto, KeypointMethod::kBoundary, KeypointMethod::kRangeImage}) {
    k.method = method;
    EXPECT_EQ(parseModel(serializeModel(model), "new.ismm").front_end.keypoints.method, method);
  }
  k.range_image.pixel_spacings = 3.5f;
  k.range_image.max_pixels = 1000;
  const KeypointParams ranged = parseModel(serializeModel(model), "new.ismm").front_end.keypoints;
  EXPECT_EQ(ranged.range_image.pixel_spacings, 3.5f);
  EXPECT_EQ(ranged.range_image.max_pixels, 1000);
  k.unorganized = KeypointMethod::kBoundary;
  EXPECT_EQ(parseModel(serializeModel(model), "new.ismm").front_end.keypoints.unorganized, KeypointMethod::kBoundary);
  k.unorganized = KeypointMethod::kRangeImage;
  k.range_image.pixel_spacings = 0;
  expectError([&] { parseModel(serializeModel(model), "broken.ismm"); }, ErrorCode::kCorruptModel,
              "range image parameters are invalid");
  k.range_image.pixel_spacings = 2.5f;

  // A file written before the keypoint fields existed: its payload has none of them.
  v1::ModelFile file;
  ASSERT_TRUE(file.ParseFromString(bytes));
  v1::ModelData data;
  ASSERT_TRUE(data.ParseFromString(file.payload()));
  auto* fe = data.mutable_front_end();
  fe->clear_keypoint_method(), fe->clear_contour_window(), fe->clear_contour_min_jump();
  fe->clear_contour_relative_jump(), fe->clear_contour_max_gap(), fe->clear_keypoint_min_spacing();
  fe->clear_keypoint_surface_spacing();
  fe->clear_unorganized_keypoint_method(), fe->clear_range_image_pixel_spacings(), fe->clear_range_image_max_pixels();
  const auto resealed = [&file](const v1::ModelData& payload) {
    file.set_payload(payload.SerializeAsString());
    file.set_payload_crc32(static_cast<uint32_t>(
        crc32(0L, reinterpret_cast<const Bytef*>(file.payload().data()), static_cast<uInt>(file.payload().size()))));
    return file.SerializeAsString();
  };
  const KeypointParams old = parseModel(resealed(data), "old.ismm").front_end.keypoints;
  EXPECT_EQ(old.method, KeypointMethod::kBoundary);
  EXPECT_EQ(old.unorganized, KeypointMethod::kBoundary) << "older models took the boundary test for clouds";
  EXPECT_EQ(old.min_spacing, 0.0f);
  EXPECT_EQ(old.surface_spacing, 0.0f) << "older models took contours only";

  fe->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_AUTO);  // contour fields still unset
  expectError([&] { parseModel(resealed(data), "broken.ismm"); }, ErrorCode::kCorruptModel,
              "contour parameters are invalid");
}

}  // namespace
}  // namespace ism
