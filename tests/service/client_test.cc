// ism-client against the real ism-server: output and exit codes (0 ok, 1 local failure,
// 2 usage, 10 + gRPC status code).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "core/training/trainer.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;

class ClientTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_ = new ServerProcess();
    dir_ = fs::path(::testing::TempDir()) / ("ism_client_test_" + std::to_string(getpid()));
    fs::create_directories(dir_ / "tum" / "depth");
    const SyntheticScene scene = smallScene();
    savePcd(scene.scene, (dir_ / "scene.pcd").string());
    // Large enough for the tiny model's calibration to find something with some confidence.
    savePcd(smallScene(0, 320, 240).scene, (dir_ / "scene320.pcd").string());
    for (int i = 0; i < 6; ++i) {
      const v1::Scene frame = pngDepthMessage(smallScene(i).depth);
      writeFileBytes((dir_ / "tum" / "depth" / (std::to_string(1305031102 + i) + ".5.png")).string(),
                     frame.depth().data());
    }
    writeFileBytes((dir_ / "broken.png").string(), "this is not a PNG");
  }
  static void TearDownTestSuite() {
    delete server_;
    fs::remove_all(dir_);
  }

  static std::string client(const std::string& arguments, int* exit_code) {
    return runCommand(std::string(ISM_CLIENT_BINARY) + " --server " + server_->address() + " " + arguments, exit_code);
  }

  static ServerProcess* server_;
  static fs::path dir_;
};
ServerProcess* ClientTest::server_ = nullptr;
fs::path ClientTest::dir_;

TEST_F(ClientTest, HealthPrintsServing) {
  int code = -1;
  const std::string out = client("health", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("SERVING"), std::string::npos) << out;
}

TEST_F(ClientTest, RecognizePrintsATable) {
  int code = -1;
  const std::string pcd = (dir_ / "scene.pcd").string();
  // In the seed's preset a zero threshold makes every Hough maximum a hypothesis, so the table has rows.
  const std::string out =
      client("recognize --preset seed --min-score 0 --max-hypotheses 3 --no-box-selection " + pcd, &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex(pcd + ": 3 hypotheses \\(model default@[0-9a-f]{8}"))) << out;
  EXPECT_NE(out.find("category"), std::string::npos) << out;
  // category, confidence, score, threshold (the zero asked for)
  EXPECT_TRUE(std::regex_search(out, std::regex("\n(dining_table|dining_chair) +[01]\\.[0-9]{3} +[0-9.]+ +0\\.000 ")))
      << out;
  EXPECT_NE(out.find("stages: decode"), std::string::npos) << out;
}

TEST_F(ClientTest, RecognizeJsonAndPicture) {
  int code = -1;
  const std::string png = (dir_ / "tum" / "depth" / "1305031102.5.png").string();
  const std::string picture = (dir_ / "picture.png").string();
  const std::string out = client("--json recognize --fx 131.25 --fy 131.25 --cx 79.5 --cy 59.5 --picture " +
                                     picture + " " + png,
                                 &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("\"input_points\":"), std::string::npos) << out;
  ASSERT_TRUE(fs::exists(picture));
  EXPECT_GT(fs::file_size(picture), 100u);
}

// The default preset's answers with their confidences, and the up the server used: the one given.
TEST_F(ClientTest, RecognizeWithUpAndMinConfidence) {
  int code = -1;
  const std::string pcd = (dir_ / "scene320.pcd").string();
  std::string out = client("recognize --up 0,0,1 --min-confidence 0.01 " + pcd, &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex(pcd + ": [1-9][0-9]* hypotheses"))) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex("\n(dining_table|dining_chair) +0\\.[0-9]{3} "))) << out;
  EXPECT_NE(out.find("\nup: (0.00, 0.00, 1.00) given, floor at "), std::string::npos) << out;

  // The same in JSON, and a higher minimum keeps fewer.
  out = client("--json recognize --up 0,0,1 --min-confidence 0.01 " + pcd, &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("\"source\":\"UP_SOURCE_GIVEN\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"upright_box\":true"), std::string::npos) << out;
  // Above the least confident answer, that one goes.
  const auto confidences = [](const std::string& text) {
    const nlohmann::json answer = nlohmann::json::parse(text);
    std::vector<float> all;
    for (const auto& h : answer.at("response").at("result").at("hypotheses")) {
      all.push_back(h.at("confidence").get<float>());
    }
    return all;
  };
  const std::vector<float> all = confidences(out);
  ASSERT_FALSE(all.empty()) << out;
  const float least = *std::min_element(all.begin(), all.end());
  ASSERT_LT(least, 0.98f) << out;
  char higher[32];
  std::snprintf(higher, sizeof(higher), "%.3f", least + 0.001f);  // at least 0.0005 above it
  const std::string fewer =
      client("--json recognize --up 0,0,1 --min-confidence " + std::string(higher) + " " + pcd, &code);
  EXPECT_EQ(code, 0) << fewer;
  const std::vector<float> kept = confidences(fewer);
  EXPECT_LT(kept.size(), all.size()) << fewer;
  for (const float c : kept) EXPECT_GE(c, std::stof(higher)) << fewer;

  // Streams send the up with every frame.
  out = client("stream --policy every --up 0,0,1 --fx 131.25 --fy 131.25 --cx 79.5 --cy 59.5 --folder " +
                   (dir_ / "tum").string(),
               &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("6 frames sent, 6 results (0 failed)"), std::string::npos) << out;
}

// What the server would refuse is a usage error here, naming the flag.
TEST_F(ClientTest, BadPresetFlagsAreUsageErrors) {
  const std::string pcd = (dir_ / "scene.pcd").string();
  for (const std::string& flags : {"--up 0,0,0", "--up 1,2", "--up 0,0,nan", "--up a,b,c"}) {
    int code = -1;
    const std::string out = client("recognize " + flags + " " + pcd, &code);
    EXPECT_EQ(code, 2) << flags << ": " << out;
    EXPECT_NE(out.find("--up"), std::string::npos) << flags << ": " << out;
  }
  for (const std::string& flags : {"--min-confidence 1", "--min-confidence -0.5", "--preset fancy"}) {
    int code = -1;
    const std::string out = client("recognize " + flags + " " + pcd, &code);
    EXPECT_EQ(code, 2) << flags << ": " << out;
    EXPECT_NE(out.find(flags.substr(0, flags.find(' '))), std::string::npos) << flags << ": " << out;
  }
}

TEST_F(ClientTest, ExitCodesFollowTheStatus) {
  int code = -1;
  std::string out = client("models show nope", &code);
  EXPECT_EQ(code, 10 + static_cast<int>(grpc::StatusCode::NOT_FOUND)) << out;
  EXPECT_NE(out.find("NOT_FOUND: unknown model 'nope'"), std::string::npos) << out;

  out = client("recognize " + (dir_ / "broken.png").string(), &code);
  EXPECT_EQ(code, 10 + static_cast<int>(grpc::StatusCode::INVALID_ARGUMENT)) << out;
  EXPECT_NE(out.find("not a PNG"), std::string::npos) << out;

  out = client("recognize --category spaceship " + (dir_ / "scene.pcd").string(), &code);
  EXPECT_EQ(code, 10 + static_cast<int>(grpc::StatusCode::NOT_FOUND)) << out;

  out = client("recognize " + (dir_ / "missing.pcd").string(), &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("missing.pcd"), std::string::npos) << out;

  out = client("recognize --no-such-flag x.pcd", &code);
  EXPECT_EQ(code, 2) << out;

  out = runCommand(std::string(ISM_CLIENT_BINARY) + " --server 127.0.0.1:1 health", &code);
  EXPECT_EQ(code, 10 + static_cast<int>(grpc::StatusCode::UNAVAILABLE)) << out;
}

TEST_F(ClientTest, ModelsListsTheModel) {
  int code = -1;
  std::string out = client("models", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(std::regex_search(out, std::regex("default +[0-9a-f]{8} +v1 .*dining_chair, dining_table"))) << out;
  out = client("models show default", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("threshold"), std::string::npos) << out;
  char shot[32];  // the model is trained with the default front end
  std::snprintf(shot, sizeof shot, "SHOT r %.3f m", defaultFrontEnd().shot.radius);
  EXPECT_NE(out.find(shot), std::string::npos) << out;
}

TEST_F(ClientTest, StreamsAFolderOfDepthPngs) {
  int code = -1;
  const std::string out = client("stream --policy every --fx 131.25 --fy 131.25 --cx 79.5 --cy 59.5 --folder " +
                                     (dir_ / "tum").string(),
                                 &code);
  EXPECT_EQ(code, 0) << out;
  for (int i = 1; i <= 6; ++i) {
    EXPECT_NE(out.find("frame " + std::to_string(i) + ": "), std::string::npos) << out;
  }
  EXPECT_NE(out.find("6 frames sent, 6 results (0 failed), 0 skipped"), std::string::npos) << out;
}

TEST_F(ClientTest, StreamWithoutASensorSaysSo) {
  int code = -1;
  const std::string out = client("stream --device", &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("no OpenNI2 depth sensor is attached"), std::string::npos) << out;
}

}  // namespace
}  // namespace ism::testing
