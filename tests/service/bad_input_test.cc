// Bad input on every RPC of the real ism-server (ism.v1.FurnitureRecognizer and grpc.health.v1):
// bytes protobuf cannot decode, lengths that disagree, NaN/Inf, zero and huge sizes, unknown
// names, invalid options, messages above the receive limit and a flood of tiny requests. Each
// must get its status code and a message naming what is wrong; afterwards the server still
// answers, and the flood leaves its resident memory bounded.
#include <arpa/inet.h>
#include <sys/stat.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <limits>
#include <map>
#include <mutex>
#include <thread>

#include "core/io/file_bytes.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/common/png_bomb.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;
using v1::FurnitureRecognizer;

constexpr int kMaxPoints = 100000;
constexpr int kMaxMessageMb = 4;
const std::string kService = "/ism.v1.FurnitureRecognizer/";
const std::string kHealthCheck = "/grpc.health.v1.Health/Check";

std::string packed(const std::vector<float>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
}

// A PNG built by hand, so that the header can say what the tests need (other bit depths,
// sizes the data does not have).
std::string pngChunk(const std::string& type, const std::string& data) {
  std::string out;
  const uint32_t length = htonl(static_cast<uint32_t>(data.size()));
  out.append(reinterpret_cast<const char*>(&length), 4);
  out += type + data;
  const uint32_t crc =
      htonl(static_cast<uint32_t>(crc32(crc32(0L, reinterpret_cast<const Bytef*>(type.data()), 4),
                                        reinterpret_cast<const Bytef*>(data.data()), static_cast<uInt>(data.size()))));
  out.append(reinterpret_cast<const char*>(&crc), 4);
  return out;
}

std::string png(uint32_t width, uint32_t height, int bit_depth, int color_type, const std::string& raw_rows) {
  std::string header(13, '\0');
  const uint32_t w = htonl(width), h = htonl(height);
  std::memcpy(header.data(), &w, 4);
  std::memcpy(header.data() + 4, &h, 4);
  header[8] = static_cast<char>(bit_depth);
  header[9] = static_cast<char>(color_type);
  std::string out("\x89PNG\r\n\x1a\n", 8);
  out += pngChunk("IHDR", header);
  if (!raw_rows.empty()) {
    uLongf size = compressBound(static_cast<uLong>(raw_rows.size()));
    std::string compressed(size, '\0');
    compress(reinterpret_cast<Bytef*>(compressed.data()), &size, reinterpret_cast<const Bytef*>(raw_rows.data()),
             static_cast<uLong>(raw_rows.size()));
    compressed.resize(size);
    out += pngChunk("IDAT", compressed);
  }
  return out + pngChunk("IEND", "");
}

// One unary call with the request's bytes exactly as given: protobuf decoding happens on the
// server only.
grpc::Status rawUnary(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                      const std::string& bytes) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  grpc::Slice slice(bytes);
  grpc::ByteBuffer request(&slice, 1), response;
  std::promise<grpc::Status> done;
  stub.UnaryCall(&context, method, grpc::StubOptions(), &request, &response,
                 [&](grpc::Status status) { done.set_value(std::move(status)); });
  return done.get_future().get();
}

// One streaming call carrying `messages` as raw bytes, then half-closed; the responses' bytes
// land in `responses`. Driven one operation at a time on a completion queue.
grpc::Status rawStream(const std::shared_ptr<grpc::Channel>& channel, const std::string& method,
                       const std::vector<std::string>& messages, std::vector<std::string>* responses) {
  grpc::GenericStub stub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
  grpc::CompletionQueue queue;
  auto next = [&] {
    void* tag = nullptr;
    bool ok = false;
    if (!queue.Next(&tag, &ok)) return false;
    return ok;
  };
  auto call = stub.PrepareCall(&context, method, &queue);
  call->StartCall(nullptr);
  next();
  for (const auto& message : messages) {
    grpc::Slice slice(message);
    grpc::ByteBuffer buffer(&slice, 1);
    call->Write(buffer, nullptr);
    if (!next()) break;  // the server ended the call; Finish says why
  }
  call->WritesDone(nullptr);
  next();
  for (;;) {
    grpc::ByteBuffer buffer;
    call->Read(&buffer, nullptr);
    if (!next()) break;
    std::vector<grpc::Slice> slices;
    (void)buffer.Dump(&slices);
    std::string bytes;
    for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
    responses->push_back(std::move(bytes));
  }
  grpc::Status status;
  call->Finish(&status, nullptr);
  next();
  queue.Shutdown();
  while (next()) {
  }
  return status;
}

// Resident memory of a process, from /proc, in MB.
double residentMb(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  }
  throw std::runtime_error("no VmRSS for pid " + std::to_string(pid));
}

::testing::AssertionResult hasStatus(const grpc::Status& status, grpc::StatusCode code, const std::string& message) {
  if (status.error_code() != code) {
    return ::testing::AssertionFailure() << "code " << status.error_code() << " instead of " << code << ": '"
                                         << status.error_message() << "'";
  }
  if (status.error_message().find(message) == std::string::npos) {
    return ::testing::AssertionFailure() << "'" << status.error_message() << "' lacks '" << message << "'";
  }
  return ::testing::AssertionSuccess();
}

class BadInputTest : public ::testing::Test {
 protected:
  // Small limits, so that each is reachable with small requests.
  static void SetUpTestSuite() {
    server_ = new ServerProcess({"--max-points", std::to_string(kMaxPoints), "--max-pixels", std::to_string(kMaxPoints),
                                 "--max-message-mb", std::to_string(kMaxMessageMb)});
    const SyntheticScene scene = smallScene();
    raw_ = new v1::Scene(rawDepthMessage(scene.depth));
    png_ = new v1::Scene(pngDepthMessage(scene.depth));
    cloud_ = new v1::Scene(cloudMessage(scene.scene));
  }
  static void TearDownTestSuite() {
    delete server_;
    delete raw_;
    delete png_;
    delete cloud_;
  }

  static std::unique_ptr<FurnitureRecognizer::Stub> stub() { return FurnitureRecognizer::NewStub(server_->channel()); }

  static grpc::Status recognize(const v1::RecognizeRequest& request, v1::RecognizeResponse* response) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(60));
    return stub()->Recognize(&context, request, response);
  }

  // Health SERVING and a good request answered: nothing before broke the server.
  static void expectStillServing() {
    auto health = grpc::health::v1::Health::NewStub(server_->channel());
    grpc::ClientContext context;
    grpc::health::v1::HealthCheckResponse serving;
    const grpc::Status checked = health->Check(&context, {}, &serving);
    ASSERT_TRUE(checked.ok()) << checked.error_message();
    EXPECT_EQ(serving.status(), grpc::health::v1::HealthCheckResponse::SERVING);
    v1::RecognizeRequest request;
    *request.mutable_scene() = *raw_;
    v1::RecognizeResponse response;
    const grpc::Status status = recognize(request, &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    EXPECT_GT(response.result().keypoints(), 0u);
  }

  static ServerProcess* server_;
  static v1::Scene *raw_, *png_, *cloud_;
};
ServerProcess* BadInputTest::server_ = nullptr;
v1::Scene* BadInputTest::raw_ = nullptr;
v1::Scene* BadInputTest::png_ = nullptr;
v1::Scene* BadInputTest::cloud_ = nullptr;

struct RawCase {
  std::string name;
  std::string method;
  std::string bytes;
  grpc::StatusCode code;
  std::string message;
};

// Bytes that are not the method's request: protobuf itself refuses them. A wrong message must
// not look like a missing method (UNIMPLEMENTED) or a server bug (INTERNAL).
TEST_F(BadInputTest, UndecodableBytesOnEveryRpc) {
  v1::RecognizeRequest recognize;
  *recognize.mutable_scene() = *png_;
  const std::string recognize_bytes = recognize.SerializeAsString();
  v1::LoadModelRequest load;
  load.set_name("default");
  load.set_path(tinyModelDirectory() + "/default.ismm");
  const std::string load_bytes = load.SerializeAsString();
  const std::string garbage("\x00\x01\x02 not protobuf \xff\xff\xff\xff\xff", 22);
  const std::string truncated_field = std::string("\x0a\x05", 2) + "ab";  // field 1 announces 5 bytes, 2 follow
  const std::string bad_utf8("\x0a\x02\xc3\x28", 4);                      // field 1, a string that is not UTF-8
  const auto invalid = grpc::StatusCode::INVALID_ARGUMENT;

  std::vector<RawCase> cases;
  const std::map<std::string, std::string> request_types{
      {"Recognize", "ism.v1.RecognizeRequest"},     {"ListModels", "ism.v1.ListModelsRequest"},
      {"GetModel", "ism.v1.GetModelRequest"},       {"LoadModel", "ism.v1.LoadModelRequest"},
      {"UnloadModel", "ism.v1.UnloadModelRequest"}, {"ReloadModels", "ism.v1.ReloadModelsRequest"}};
  for (const auto& [rpc, type] : request_types) {
    const std::string expected = "not a valid " + type;
    cases.push_back({rpc + ", garbage", kService + rpc, garbage, invalid, expected});
    cases.push_back({rpc + ", truncated field", kService + rpc, truncated_field, invalid, expected});
  }
  for (const std::string rpc : {"GetModel", "LoadModel", "UnloadModel"}) {
    cases.push_back(
        {rpc + ", string not UTF-8", kService + rpc, bad_utf8, invalid, "not a valid ism.v1." + rpc + "Request"});
  }
  // Recognize's request_id is field 1 as well.
  cases.push_back({"Recognize, request_id not UTF-8", kService + "Recognize", bad_utf8, invalid,
                   "not a valid ism.v1.RecognizeRequest"});
  cases.push_back({"Recognize, cut in the middle of its depth image", kService + "Recognize",
                   recognize_bytes.substr(0, recognize_bytes.size() / 2), invalid,
                   "not a valid ism.v1.RecognizeRequest"});
  cases.push_back({"LoadModel, cut in its path", kService + "LoadModel", load_bytes.substr(0, load_bytes.size() - 3),
                   invalid, "not a valid ism.v1.LoadModelRequest"});
  // gRPC's own health service: its answers are gRPC's, listed here so that every RPC is covered.
  cases.push_back({"Health, garbage", kHealthCheck, garbage, invalid, "could not parse request"});
  cases.push_back({"Health, truncated field", kHealthCheck, truncated_field, invalid, "could not parse request"});
  cases.push_back({"Health, unknown service", kHealthCheck, std::string("\x0a\x05ghost", 7),
                   grpc::StatusCode::NOT_FOUND, "service name unknown"});
  cases.push_back({"no such method", kService + "Transmogrify", "", grpc::StatusCode::UNIMPLEMENTED, ""});

  for (const auto& c : cases) {
    EXPECT_TRUE(hasStatus(rawUnary(server_->channel(), c.method, c.bytes), c.code, c.message)) << c.name;
  }
  // The size of what arrived helps whoever reads the log find the sender's bug.
  EXPECT_TRUE(hasStatus(rawUnary(server_->channel(), kService + "GetModel", garbage), invalid, "(22 bytes)"));
  expectStillServing();
}

// A request of 0 bytes is a valid message with every field at its default: each RPC answers it
// as it would any request without those fields, never as bytes that do not decode.
TEST_F(BadInputTest, ARequestOfZeroBytesIsAnEmptyMessage) {
  const std::vector<RawCase> cases{
      {"Recognize", kService + "Recognize", "", grpc::StatusCode::INVALID_ARGUMENT, "Recognize: no scene given"},
      {"ListModels", kService + "ListModels", "", grpc::StatusCode::OK, ""},
      {"GetModel", kService + "GetModel", "", grpc::StatusCode::OK, ""},  // the only model
      {"LoadModel", kService + "LoadModel", "", grpc::StatusCode::INVALID_ARGUMENT, "LoadModel: name is empty"},
      {"UnloadModel", kService + "UnloadModel", "", grpc::StatusCode::INVALID_ARGUMENT, "UnloadModel: name is empty"},
  };
  for (const auto& c : cases) {
    EXPECT_TRUE(hasStatus(rawUnary(server_->channel(), c.method, c.bytes), c.code, c.message)) << c.name;
  }
  expectStillServing();
}

// Above --max-message-mb gRPC refuses the message before any handler sees it.
TEST_F(BadInputTest, OversizedMessagesOnEveryRpc) {
  const std::string oversized(kMaxMessageMb * 1024 * 1024 + 100, '\0');
  for (const std::string rpc : {"Recognize", "ListModels", "GetModel", "LoadModel", "UnloadModel", "ReloadModels"}) {
    EXPECT_TRUE(hasStatus(rawUnary(server_->channel(), kService + rpc, oversized), grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "larger than max"))
        << rpc;
  }
  EXPECT_TRUE(hasStatus(rawUnary(server_->channel(), kHealthCheck, oversized), grpc::StatusCode::RESOURCE_EXHAUSTED,
                        "larger than max"));
  std::vector<std::string> responses;
  EXPECT_TRUE(hasStatus(rawStream(server_->channel(), kService + "StreamFrames", {oversized}, &responses),
                        grpc::StatusCode::RESOURCE_EXHAUSTED, "larger than max"));
  EXPECT_TRUE(responses.empty());
  // A well-formed request with a cloud of that size is refused the same way.
  v1::RecognizeRequest request;
  request.mutable_scene()->mutable_cloud()->set_xyz(std::string(12 * 400000, '\0'));
  v1::RecognizeResponse response;
  EXPECT_TRUE(hasStatus(recognize(request, &response), grpc::StatusCode::RESOURCE_EXHAUSTED, "larger than max"));
  expectStillServing();
}

struct SceneCase {
  std::string name;
  std::function<void(v1::RecognizeRequest*)> spoil;
  grpc::StatusCode code;
  std::string message;
};

// The Recognize (and StreamFrames frame) inputs that cannot be served, beyond those of
// ServiceTest.EveryBadInputGetsItsStatusAndTheServerGoesOn.
std::vector<SceneCase> badScenes(const v1::Scene& raw, const v1::Scene& png, const v1::Scene& cloud) {
  const auto invalid = grpc::StatusCode::INVALID_ARGUMENT;
  const auto exhausted = grpc::StatusCode::RESOURCE_EXHAUSTED;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto with = [](const v1::Scene& scene, std::function<void(v1::Scene*)> change) {
    return [scene, change](v1::RecognizeRequest* r) {
      *r->mutable_scene() = scene;
      change(r->mutable_scene());
    };
  };
  auto options = [raw](std::function<void(v1::RecognitionOptions*)> change) {
    return [raw, change](v1::RecognizeRequest* r) {
      *r->mutable_scene() = raw;
      change(r->mutable_options());
    };
  };
  std::vector<float> six_points(18, 0.5f);
  const std::string depth_png = png.depth().data();
  return {
      // Lengths that disagree.
      {"xyz shorter than one point", with(cloud, [](auto* s) { s->mutable_cloud()->set_xyz(std::string(11, '\0')); }),
       invalid, "scene.cloud.xyz has 11 bytes, not a multiple of 12"},
      {"organized with height 0",
       with(cloud,
            [=](auto* s) {
              s->mutable_cloud()->set_xyz(packed(six_points));
              s->mutable_cloud()->set_width(6);
              s->mutable_cloud()->set_height(0);
            }),
       invalid, "declared 6x0 = 0 points but xyz has 6"},
      {"organized size far beyond the points",
       with(cloud,
            [=](auto* s) {
              s->mutable_cloud()->set_xyz(packed(six_points));
              s->mutable_cloud()->set_width(65536);
              s->mutable_cloud()->set_height(65536);
            }),
       invalid, "declared 65536x65536 = 4294967296 points but xyz has 6"},
      {"rgb for fewer points than xyz",
       with(cloud,
            [=](auto* s) {
              s->mutable_cloud()->set_xyz(packed(six_points));
              s->mutable_cloud()->set_rgb(std::string(3 * 5, '\x7f'));
            }),
       invalid, "scene.cloud.rgb has 15 bytes but xyz has 6 points (expected 18 bytes)"},
      {"raw depth without data", with(raw, [](auto* s) { s->mutable_depth()->clear_data(); }), invalid,
       "scene.depth.data has 0 bytes but a 160x120 uint16 image needs 38400"},
      {"raw depth with an odd byte count", with(raw, [](auto* s) { s->mutable_depth()->mutable_data()->pop_back(); }),
       invalid, "scene.depth.data has 38399 bytes but a 160x120 uint16 image needs 38400"},
      {"PNG without data", with(png, [](auto* s) { s->mutable_depth()->clear_data(); }), invalid,
       "scene.depth.data (0 bytes) is not a PNG image"},
      {"PNG cut in half",
       with(png, [depth_png](auto* s) { s->mutable_depth()->set_data(depth_png.substr(0, depth_png.size() / 2)); }),
       invalid, "broken PNG data"},
      {"8-bit PNG",
       with(png,
            [](auto* s) {
              std::string rows;
              for (int y = 0; y < 120; ++y) rows += std::string(1, '\0') + std::string(160, '\x40');
              s->mutable_depth()->set_data(ism::testing::png(160, 120, 8, 0, rows));
            }),
       invalid, "expected a 16-bit single-channel depth image"},
      {"RGB PNG",
       with(png,
            [](auto* s) {
              std::string rows;
              for (int y = 0; y < 120; ++y) rows += std::string(1, '\0') + std::string(160 * 6, '\x40');
              s->mutable_depth()->set_data(ism::testing::png(160, 120, 16, 2, rows));
            }),
       invalid, "expected a 16-bit single-channel depth image"},
      // NaN and Inf.
      {"only +Inf points",
       with(cloud, [=](auto* s) { s->mutable_cloud()->set_xyz(packed(std::vector<float>(150, inf))); }), invalid,
       "none of its 50 points is finite"},
      {"only NaN and -Inf points",
       with(cloud,
            [=](auto* s) {
              std::vector<float> xyz(300);
              for (size_t i = 0; i < xyz.size(); ++i) xyz[i] = i % 2 ? nan : -inf;
              s->mutable_cloud()->set_xyz(packed(xyz));
            }),
       invalid, "none of its 100 points is finite"},
      // Among points in range such points are dropped (PointsBeyondTheSensorRangeAreDroppedAndCounted).
      {"only finite coordinates near the float limit",
       with(cloud,
            [](auto* s) {
              s->mutable_cloud()->clear_width();
              s->mutable_cloud()->clear_height();
              s->mutable_cloud()->set_xyz(packed({1e30f, 1e30f, 1e30f, -3e38f, 0, 3e38f}));
            }),
       invalid, "scene: all 2 points are farther than 100 m from scene.sensor_origin"},
      {"NaN sensor origin", with(cloud, [=](auto* s) { s->mutable_sensor_origin()->set_y(nan); }), invalid,
       "scene.sensor_origin / sensor_orientation contain NaN or Inf"},
      {"Inf sensor orientation", with(raw, [=](auto* s) { s->mutable_sensor_orientation()->set_w(inf); }), invalid,
       "scene.sensor_origin / sensor_orientation contain NaN or Inf"},
      {"negative fy", with(raw, [](auto* s) { s->mutable_depth()->mutable_intrinsics()->set_fy(-525); }), invalid,
       "scene.depth.intrinsics.fy must be > 0, got -525"},
      {"Inf fx", with(png, [=](auto* s) { s->mutable_depth()->mutable_intrinsics()->set_fx(inf); }), invalid,
       "scene.depth.intrinsics.fx must be > 0, got inf"},
      {"NaN cx", with(raw, [=](auto* s) { s->mutable_depth()->mutable_intrinsics()->set_cx(nan); }), invalid,
       "scene.depth.intrinsics.cx is not finite"},
      {"zero depth scale", with(raw, [](auto* s) { s->mutable_depth()->mutable_intrinsics()->set_depth_scale(0); }),
       invalid, "scene.depth.intrinsics.depth_scale must be > 0, got 0"},
      // Huge sizes: refused before anything of that size is allocated.
      {"more points than the limit",
       with(cloud, [](auto* s) { s->mutable_cloud()->set_xyz(std::string(12 * 300000, '\0')); }), exhausted,
       "scene.cloud points has 300000, more than the server's limit of 100000"},
      {"raw depth declared 4294967295 x 4294967295",
       with(raw,
            [](auto* s) {
              s->mutable_depth()->set_width(4294967295u);
              s->mutable_depth()->set_height(4294967295u);
            }),
       exhausted, "scene.depth pixels has 18446744065119617025, more than the server's limit of 100000"},
      {"PNG header announcing 100000 x 100000",
       with(png, [](auto* s) { s->mutable_depth()->set_data(ism::testing::png(100000, 100000, 16, 0, "")); }),
       exhausted, "scene.depth PNG pixels has 10000000000, more than the server's limit of 100000"},
      // 1x1 whose data inflates to 512 MB (~0.5 MB on the wire): refused after 3 bytes, not after a
      // worker spent seconds inflating it.
      {"PNG decompression bomb",
       with(png,
            [](auto* s) {
              s->mutable_depth()->clear_width();
              s->mutable_depth()->clear_height();
              s->mutable_depth()->set_data(ism::testing::depthPngBomb(512));
            }),
       invalid, "request PNG: the PNG's image data inflates to more than the 3 bytes a 1x1 16-bit image holds"},
      // Options.
      {"negative k", options([](auto* o) {
         o->mutable_strategy()->set_activation(v1::ACTIVATION_STRATEGY_KNN);
         o->mutable_strategy()->set_k(-3);
       }),
       invalid, "options.strategy.k must be >= 0, got -3"},
      {"negative cutoff", options([](auto* o) {
         o->mutable_strategy()->set_activation(v1::ACTIVATION_STRATEGY_CUTOFF);
         o->mutable_strategy()->set_cutoff(-0.5f);
       }),
       invalid, "options.strategy.cutoff must be >= 0, got -0.5"},
      {"NaN cutoff", options([=](auto* o) {
         o->mutable_strategy()->set_activation(v1::ACTIVATION_STRATEGY_CUTOFF);
         o->mutable_strategy()->set_cutoff(nan);
       }),
       invalid, "options.strategy.cutoff must be >= 0, got nan"},
      {"k beyond the codebook", options([](auto* o) {
         o->mutable_strategy()->set_activation(v1::ACTIVATION_STRATEGY_KNN);
         o->mutable_strategy()->set_k(1000000000);
       }),
       invalid, "options.strategy.k = 1000000000 is more than the 40 codewords of the model's global codebook"},
      {"cutoff beyond any distance", options([](auto* o) {
         o->mutable_strategy()->set_activation(v1::ACTIVATION_STRATEGY_CUTOFF);
         o->mutable_strategy()->set_cutoff(1e30f);
       }),
       invalid, "options.strategy.cutoff = 1e+30 is more than 2, the largest distance between a descriptor"},
      {"NaN min_score", options([=](auto* o) { o->set_min_score(nan); }), invalid, "options.min_score is not finite"},
      {"Inf min_score", options([=](auto* o) { o->set_min_score(inf); }), invalid, "options.min_score is not finite"},
      {"unknown codebook type",
       options([](auto* o) { o->mutable_strategy()->set_codebook(static_cast<v1::CodebookType>(9)); }), invalid,
       "options.strategy.codebook 9 is not supported"},
      {"unknown activation strategy",
       options([](auto* o) { o->mutable_strategy()->set_activation(static_cast<v1::ActivationStrategy>(9)); }), invalid,
       "options.strategy.activation 9 is not supported"},
      {"unknown vote weighting",
       options([](auto* o) { o->mutable_strategy()->set_weighting(static_cast<v1::VoteWeighting>(-2)); }), invalid,
       "options.strategy.weighting -2 is not supported"},
      {"empty category name", options([](auto* o) { o->add_categories(""); }), grpc::StatusCode::NOT_FOUND,
       "category '' is not in the model (it has: dining_chair, dining_table)"},
      {"unknown model", options([](auto* o) { o->set_model("furniture-v2"); }), grpc::StatusCode::NOT_FOUND,
       "unknown model 'furniture-v2' (loaded: default)"},
  };
}

TEST_F(BadInputTest, RecognizeRequestsThatCannotBeServed) {
  for (const auto& c : badScenes(*raw_, *png_, *cloud_)) {
    v1::RecognizeRequest request;
    c.spoil(&request);
    v1::RecognizeResponse response;
    EXPECT_TRUE(hasStatus(recognize(request, &response), c.code, c.message)) << c.name;
  }
  expectStillServing();
}

// Odd but servable: non-finite points among finite ones are dropped, not refused.
TEST_F(BadInputTest, NonFinitePointsAmongFiniteOnesAreDropped) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  v1::RecognizeRequest request;
  *request.mutable_scene() = *cloud_;
  std::string* xyz = request.mutable_scene()->mutable_cloud()->mutable_xyz();
  const size_t finite = xyz->size() / 12;
  *xyz += packed({inf, 0, 0, 0, -inf, 0, nan, nan, nan, 1, 2, inf});
  v1::RecognizeResponse response;
  const grpc::Status status = recognize(request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.result().input_points(), finite);
  EXPECT_GT(response.result().keypoints(), 0u);
}

// A stray point far beyond any sensor's range (1e30 here) used to fail the frame in the voxel
// grid: such points are dropped and counted, and the frame is recognised from the rest.
TEST_F(BadInputTest, PointsBeyondTheSensorRangeAreDroppedAndCounted) {
  v1::RecognizeRequest request;
  *request.mutable_scene() = *cloud_;
  std::string* xyz = request.mutable_scene()->mutable_cloud()->mutable_xyz();
  const size_t in_range = xyz->size() / 12;
  std::vector<float> stray;
  for (int i = 0; i < 1000; ++i) stray.insert(stray.end(), {1e30f, (i % 2 ? -1 : 1) * 1e30f, 1.0f});
  stray.insert(stray.end(), {150.0f, 0.0f, 0.0f});  // beyond the default 100 m
  *xyz += packed(stray);
  v1::RecognizeResponse response;
  const grpc::Status status = recognize(request, &response);
  ASSERT_TRUE(status.ok()) << status.error_message();
  EXPECT_EQ(response.result().input_points(), in_range);
  EXPECT_EQ(response.result().out_of_range_points(), 1001u);
  EXPECT_GT(response.result().keypoints(), 0u);
}

// A scene in the wrong units (here millimetres ten times over) has nothing within range: it is
// refused with what to check, not with a voxel count.
TEST_F(BadInputTest, ASceneInTheWrongUnitsIsRefusedSayingSo) {
  v1::RecognizeRequest request;
  *request.mutable_scene() = *cloud_;
  std::string* xyz = request.mutable_scene()->mutable_cloud()->mutable_xyz();
  for (size_t at = 0; at < xyz->size(); at += 4) {
    float v;
    std::memcpy(&v, xyz->data() + at, 4);
    v *= 1e4f;
    std::memcpy(xyz->data() + at, &v, 4);
  }
  auto* origin = request.mutable_scene()->mutable_sensor_origin();
  origin->set_x(origin->x() * 1e4f);
  origin->set_y(origin->y() * 1e4f);
  origin->set_z(origin->z() * 1e4f);
  v1::RecognizeResponse response;
  EXPECT_TRUE(hasStatus(recognize(request, &response), grpc::StatusCode::INVALID_ARGUMENT,
                        " points are farther than 100 m from scene.sensor_origin (the nearest at "));
}

// A frame fails alone with the same status as the request would, and the stream goes on.
TEST_F(BadInputTest, EveryBadFrameFailsAloneInAStream) {
  const auto cases = badScenes(*raw_, *png_, *cloud_);
  auto call_stub = stub();
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
  auto stream = call_stub->StreamFrames(&context);
  // Frame 0 and the last frame are good ones; settings travel with every frame, since a frame's
  // options are part of what may be wrong with it.
  std::thread writer([&] {
    for (size_t i = 0; i <= cases.size() + 1; ++i) {
      v1::RecognizeRequest spoiled;
      *spoiled.mutable_scene() = *raw_;
      if (i >= 1 && i <= cases.size()) cases[i - 1].spoil(&spoiled);
      v1::StreamFramesRequest frame;
      frame.set_frame_id(i);
      *frame.mutable_settings()->mutable_options() = spoiled.options();
      *frame.mutable_scene() = spoiled.scene();
      if (!stream->Write(frame)) break;
    }
    stream->WritesDone();
  });
  std::vector<v1::FrameResult> results;
  for (v1::FrameResult result; stream->Read(&result);) results.push_back(result);
  writer.join();
  const grpc::Status status = stream->Finish();
  ASSERT_TRUE(status.ok()) << status.error_message();
  ASSERT_EQ(results.size(), cases.size() + 2);
  EXPECT_TRUE(results.front().has_result()) << results.front().error().message();
  EXPECT_TRUE(results.back().has_result()) << results.back().error().message();
  for (size_t i = 0; i < cases.size(); ++i) {
    const auto& r = results[i + 1];
    EXPECT_EQ(r.frame_id(), i + 1);
    ASSERT_TRUE(r.has_error()) << cases[i].name;
    EXPECT_TRUE(hasStatus({static_cast<grpc::StatusCode>(r.error().code()), r.error().message()}, cases[i].code,
                          cases[i].message))
        << cases[i].name;
  }
  expectStillServing();
}

// What is wrong with the stream itself ends it, with the reason; frames before it are answered.
TEST_F(BadInputTest, AStreamThatCannotGoOnEndsWithTheReason) {
  auto frame = [&](uint64_t id) {
    v1::StreamFramesRequest request;
    request.set_frame_id(id);
    *request.mutable_scene() = *png_;
    return request;
  };
  {
    // An unknown backpressure policy.
    v1::StreamFramesRequest bad = frame(2);
    bad.mutable_settings()->set_policy(static_cast<v1::BackpressurePolicy>(9));
    std::vector<std::string> responses;
    const grpc::Status status = rawStream(server_->channel(), kService + "StreamFrames",
                                          {frame(1).SerializeAsString(), bad.SerializeAsString()}, &responses);
    EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT, "settings.policy 9 (frame 2) is not supported"));
  }
  {
    // A message protobuf cannot decode, between two good frames: the stream cannot know which
    // frame it was, so it ends there instead of reading it as the client's half-close.
    std::vector<std::string> responses;
    const std::string garbage("\x00\x01\x02 not protobuf", 16);
    const grpc::Status status =
        rawStream(server_->channel(), kService + "StreamFrames",
                  {frame(1).SerializeAsString(), garbage, frame(3).SerializeAsString()}, &responses);
    EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT,
                          "message 2 of the stream (16 bytes) is not a valid ism.v1.StreamFramesRequest"));
    ASSERT_EQ(responses.size(), 1u);
    for (const auto& bytes : responses) {
      v1::FrameResult result;
      ASSERT_TRUE(result.ParseFromString(bytes));
      EXPECT_EQ(result.frame_id(), 1u);
      EXPECT_TRUE(result.has_result()) << result.error().message();
    }
  }
  {
    // Truncated in the middle of the first frame's scene.
    const std::string bytes = frame(1).SerializeAsString();
    std::vector<std::string> responses;
    const grpc::Status status =
        rawStream(server_->channel(), kService + "StreamFrames", {bytes.substr(0, bytes.size() - 10)}, &responses);
    EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT,
                          "message 1 of the stream (" + std::to_string(bytes.size() - 10) +
                              " bytes) is not a valid ism.v1.StreamFramesRequest"));
    EXPECT_TRUE(responses.empty());
  }
  expectStillServing();
}

// EVERY_FRAME frames 1-6, then a message that ends the stream: the frames read before it (some
// still queued when it arrives) are each answered before the stream ends, and the final status
// names what was read but not processed.
TEST_F(BadInputTest, EveryFrameReadBeforeABadMessageIsAnswered) {
  std::vector<std::string> frames;
  for (uint64_t id = 1; id <= 6; ++id) {
    v1::StreamFramesRequest request;
    if (id == 1) request.mutable_settings()->set_policy(v1::BACKPRESSURE_POLICY_EVERY_FRAME);
    request.set_frame_id(id);
    *request.mutable_scene() = *png_;
    frames.push_back(request.SerializeAsString());
  }
  v1::StreamFramesRequest unknown_policy;
  unknown_policy.set_frame_id(7);
  unknown_policy.mutable_settings()->set_policy(static_cast<v1::BackpressurePolicy>(9));
  *unknown_policy.mutable_scene() = *png_;
  const std::string garbage("\x00\x01\x02 not protobuf", 16);
  const std::vector<std::pair<std::string, std::string>> endings{
      {garbage, "message 7 of the stream (16 bytes) is not a valid ism.v1.StreamFramesRequest"},
      {unknown_policy.SerializeAsString(), "settings.policy 9 (frame 7) is not supported"}};
  for (const auto& [ending, reason] : endings) {
    std::vector<std::string> messages = frames;
    messages.push_back(ending);
    std::vector<std::string> responses;
    const grpc::Status status = rawStream(server_->channel(), kService + "StreamFrames", messages, &responses);
    EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT, reason));
    EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT, "every frame read before it was answered"));
    if (ending != garbage) {
      EXPECT_TRUE(hasStatus(status, grpc::StatusCode::INVALID_ARGUMENT, "not processed: frame 7"));
    }
    std::vector<uint64_t> answered;
    for (const auto& bytes : responses) {
      v1::FrameResult result;
      ASSERT_TRUE(result.ParseFromString(bytes));
      EXPECT_TRUE(result.has_result()) << result.error().message();
      answered.push_back(result.frame_id());
    }
    EXPECT_EQ(answered, (std::vector<uint64_t>{1, 2, 3, 4, 5, 6})) << reason;
  }
  expectStillServing();
}

// Bad LoadModel requests, with a model folder of the test's own: files that are not models, and
// paths that are not regular files of that folder, none of which may block or answer with what a
// file holds.
TEST_F(BadInputTest, ModelAdministrationRequestsThatCannotBeServed) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ism_bad_input_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string model = readFileBytes(tinyModelDirectory() + "/default.ismm");
  writeFileBytes((dir / "default.ismm").string(), model);
  // The smallest limit in MB the test model fits under (its size follows what training stores).
  const size_t limit_mb = model.size() / (1 << 20) + 1;
  ServerProcess server({"--models", dir.string(), "--max-model-mb", std::to_string(limit_mb)});
  fs::create_directories(dir / "a_directory.ismm");
  writeFileBytes((dir / "truncated.ismm").string(), model.substr(0, model.size() / 2));
  writeFileBytes((dir / "garbage.ismm").string(), std::string("\x00\x01\x02 this is no model", 21));
  writeFileBytes((dir / "empty.ismm").string(), "");
  writeFileBytes((dir / "secret.ismm").string(), "SECRET-API-KEY-0123456789abcdef!");
  writeFileBytes((dir / "large.ismm").string(), std::string((limit_mb << 20) + 1, 'x'));
  std::string damaged = model;
  damaged[damaged.size() / 2] ^= 0x5a;
  writeFileBytes((dir / "damaged.ismm").string(), damaged);
  ASSERT_EQ(mkfifo((dir / "fifo.ismm").c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", dir / "zero.ismm");
  auto path = [&](const char* name) { return (dir / name).string(); };
  auto s = FurnitureRecognizer::NewStub(server.channel());
  const auto failed = grpc::StatusCode::FAILED_PRECONDITION;
  const auto invalid = grpc::StatusCode::INVALID_ARGUMENT;
  const auto not_found = grpc::StatusCode::NOT_FOUND;

  struct LoadCase {
    std::string name, path;
    grpc::StatusCode code;
    std::string message;
  };
  const std::string unparsable = ": not a model file or truncated (the ModelFile envelope does not parse)";
  const std::string unreadable = ": not a readable regular file";
  const std::string outside = "is not in the model folder " + dir.string() + ": only files there are loaded";
  const std::vector<LoadCase> loads{
      {"", path("garbage.ismm"), invalid, "LoadModel: name is empty"},
      {"other", "", invalid, "LoadModel: path is empty"},
      {"other", path("truncated.ismm"), failed, path("truncated.ismm") + unparsable},
      {"other", "garbage.ismm", failed, path("garbage.ismm") + unparsable},  // relative to the folder
      {"other", path("empty.ismm"), failed, path("empty.ismm") + ": wrong magic: not a model file"},
      {"other", path("damaged.ismm"), failed,
       path("damaged.ismm") + ": CRC-32 mismatch (the file is truncated or damaged)"},
      {"other", path("large.ismm"), grpc::StatusCode::RESOURCE_EXHAUSTED,
       path("large.ismm") + ": larger than the " + std::to_string(limit_mb << 20) +
           " bytes a model file may have here"},
      // Not regular files: refused before a byte is read (a FIFO would block, /dev/zero never end).
      {"other", path("a_directory.ismm"), not_found, path("a_directory.ismm") + unreadable},
      {"other", path("fifo.ismm"), not_found, path("fifo.ismm") + unreadable},
      {"other", path("zero.ismm"), not_found, path("zero.ismm") + unreadable},
      {"other", path("absent.ismm"), not_found, path("absent.ismm") + unreadable},
      // Outside the folder: the same answer whether the file exists or not.
      {"other", "/dev/zero", invalid, "LoadModel: path '/dev/zero' " + outside},
      {"other", "/etc/passwd", invalid, "LoadModel: path '/etc/passwd' " + outside},
      {"other", "/etc/no-such-file", invalid, "LoadModel: path '/etc/no-such-file' " + outside},
      {"other", "../default.ismm", invalid, "LoadModel: path '../default.ismm' " + outside},
      {"other", path("../x/../default.ismm"), invalid, outside},
      // The loaded default must survive a failed replacement.
      {"default", path("truncated.ismm"), failed, path("truncated.ismm") + unparsable},
  };
  for (const auto& c : loads) {
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    v1::LoadModelRequest request;
    request.set_name(c.name);
    request.set_path(c.path);
    v1::ModelInfo info;
    EXPECT_TRUE(hasStatus(s->LoadModel(&context, request, &info), c.code, c.message)) << c.name << " " << c.path;
  }
  {
    // What a file holds is never echoed.
    grpc::ClientContext context;
    v1::LoadModelRequest request;
    request.set_name("other");
    request.set_path(path("secret.ismm"));
    v1::ModelInfo info;
    const grpc::Status status = s->LoadModel(&context, request, &info);
    EXPECT_EQ(status.error_code(), failed);
    EXPECT_EQ(status.error_message().find("SECRET"), std::string::npos) << status.error_message();
  }
  {
    grpc::ClientContext context;
    v1::GetModelRequest request;
    request.set_name("../default");
    v1::ModelInfo info;
    EXPECT_TRUE(hasStatus(s->GetModel(&context, request, &info), grpc::StatusCode::NOT_FOUND,
                          "unknown model '../default' (loaded: default)"));
  }
  {
    grpc::ClientContext context;
    v1::UnloadModelRequest request;
    v1::UnloadModelResponse response;
    EXPECT_TRUE(hasStatus(s->UnloadModel(&context, request, &response), grpc::StatusCode::INVALID_ARGUMENT,
                          "UnloadModel: name is empty"));
  }
  grpc::ClientContext context;
  v1::ListModelsResponse models;
  ASSERT_TRUE(s->ListModels(&context, {}, &models).ok());
  ASSERT_EQ(models.models_size(), 1);
  EXPECT_EQ(models.models(0).name(), "default");
  EXPECT_EQ(models.models(0).path(), path("default.ismm"));
  v1::RecognizeRequest request;
  *request.mutable_scene() = *raw_;
  grpc::ClientContext recognize_context;
  v1::RecognizeResponse response;
  EXPECT_TRUE(s->Recognize(&recognize_context, request, &response).ok());
  fs::remove_all(dir);
}

// Thousands of tiny requests, good and bad, from many threads at once: each gets its own
// answer and the server's memory stays bounded (gRPC and the worker queue must not keep what
// they were sent).
TEST_F(BadInputTest, AFloodOfTinyRequestsLeavesMemoryBounded) {
  constexpr int kThreads = 16, kPerThread = 250;
  const double before_mb = residentMb(server_->pid());
  struct Tiny {
    std::function<grpc::Status(FurnitureRecognizer::Stub*, const std::shared_ptr<grpc::Channel>&)> call;
    grpc::StatusCode code;
    std::string message;
  };
  const std::vector<Tiny> kinds{
      {[](auto* stub, const auto&) {
         grpc::ClientContext context;
         v1::RecognizeResponse response;
         return stub->Recognize(&context, v1::RecognizeRequest(), &response);
       },
       grpc::StatusCode::INVALID_ARGUMENT, "Recognize: no scene given"},
      {[](auto* stub, const auto&) {
         grpc::ClientContext context;
         v1::RecognizeRequest request;
         request.mutable_scene()->mutable_cloud()->set_xyz(std::string(13, '\0'));
         v1::RecognizeResponse response;
         return stub->Recognize(&context, request, &response);
       },
       grpc::StatusCode::INVALID_ARGUMENT, "13 bytes, not a multiple of 12"},
      {[](auto* stub, const auto&) {
         grpc::ClientContext context;
         v1::ListModelsResponse response;
         return stub->ListModels(&context, {}, &response);
       },
       grpc::StatusCode::OK, ""},
      {[](auto* stub, const auto&) {
         grpc::ClientContext context;
         v1::GetModelRequest request;
         request.set_name("ghost");
         v1::ModelInfo response;
         return stub->GetModel(&context, request, &response);
       },
       grpc::StatusCode::NOT_FOUND, "unknown model 'ghost'"},
      {[](auto*, const auto& channel) {
         return rawUnary(channel, kService + "GetModel", std::string("\x00garbage", 8));
       },
       grpc::StatusCode::INVALID_ARGUMENT, "not a valid ism.v1.GetModelRequest"},
  };
  std::atomic<int> wrong{0};
  std::mutex mutex;
  std::string first_wrong;
  std::map<grpc::StatusCode, int> counts;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      // A channel per thread: many HTTP/2 connections, as a fleet of robots would open.
      grpc::ChannelArguments args;
      args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
      const auto channel = grpc::CreateCustomChannel(server_->address(), grpc::InsecureChannelCredentials(), args);
      // Connected first: gRPC 1.51's first connection attempt sometimes fails at once, and the
      // calls are about the answers.
      EXPECT_TRUE(channel->WaitForConnected(std::chrono::system_clock::now() + std::chrono::minutes(1)));
      auto stub = FurnitureRecognizer::NewStub(channel);
      std::map<grpc::StatusCode, int> mine;
      for (int i = 0; i < kPerThread; ++i) {
        const Tiny& kind = kinds[static_cast<size_t>(t + i) % kinds.size()];
        const grpc::Status status = kind.call(stub.get(), channel);
        ++mine[status.error_code()];
        if (!hasStatus(status, kind.code, kind.message)) {
          std::lock_guard<std::mutex> lock(mutex);
          if (wrong++ == 0) first_wrong = hasStatus(status, kind.code, kind.message).message();
        }
      }
      std::lock_guard<std::mutex> lock(mutex);
      for (const auto& [code, n] : mine) counts[code] += n;
    });
  }
  for (auto& t : threads) t.join();
  const double after_mb = residentMb(server_->pid());
  EXPECT_EQ(wrong, 0) << "first: " << first_wrong;
  int total = 0;
  for (const auto& [code, n] : counts) total += n;
  EXPECT_EQ(total, kThreads * kPerThread);
  EXPECT_EQ(counts[grpc::StatusCode::INVALID_ARGUMENT], kThreads * kPerThread * 3 / 5);
  std::cout << kThreads * kPerThread << " tiny requests; server resident " << before_mb << " MB before, " << after_mb
            << " MB after\n";
  // Generous: gRPC keeps per-connection buffers and the allocator keeps freed pages; what
  // must not happen is memory per request (4000 requests x a leaked buffer each).
  EXPECT_LT(after_mb - before_mb, 200.0);
  expectStillServing();
}

}  // namespace
}  // namespace ism::testing
