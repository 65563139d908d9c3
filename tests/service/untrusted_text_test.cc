// What a client sends and the server logs or sends back: request ids, model and category names.
// None of it may forge a log line, fill the log, or grow a status past what gRPC carries.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/io/file_bytes.h"
#include "server/untrusted_text.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;
using server::capped;
using server::kMaxStatusMessage;
using server::loggable;

TEST(UntrustedText, ControlCharactersAndBackslashesAreEscaped) {
  EXPECT_EQ(loggable("id-1"), "id-1");
  EXPECT_EQ(loggable("a\nb\x1b[31mc\\d"), "a\\x0ab\\x1b[31mc\\x5cd");
  EXPECT_EQ(loggable(std::string("\0\x7f\xc3\xa9", 4)), "\\x00\\x7f\\xc3\\xa9");
}

TEST(UntrustedText, LongTextIsCutAndSaysHowLongItWas) {
  EXPECT_EQ(loggable(std::string(1000, 'x'), 10), "xxxxxxxxxx...(1000 bytes)");
  EXPECT_EQ(loggable(std::string(10, 'x'), 10), "xxxxxxxxxx");
  EXPECT_EQ(capped(std::string(10, 'x'), 10), "xxxxxxxxxx");
  EXPECT_EQ(capped(std::string(11, 'x'), 10), "xxxxxxxxxx...(11 bytes in all)");
}

TEST(UntrustedText, AMessageIsNotCutInsideACharacter) {
  // "é" is two bytes: a cut after byte 3 would split the second one.
  EXPECT_EQ(capped("ab\xc3\xa9\xc3\xa9", 3), "ab...(6 bytes in all)");
  EXPECT_EQ(capped("ab\xc3\xa9\xc3\xa9", 4), "ab\xc3\xa9...(6 bytes in all)");
}

std::string readLog(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class UntrustedTextServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("ism_untrusted_text_test_" + std::to_string(getpid()));
    fs::create_directories(dir_);
    writeFileBytes((dir_ / "default.ismm").string(), readFileBytes(tinyModelDirectory() + "/default.ismm"));
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

TEST_F(UntrustedTextServiceTest, ARequestIdCannotForgeALogLineNorFillTheLog) {
  const std::string log = (dir_ / "server.log").string();
  ServerProcess server({"--models", dir_.string(), "--log-level", "info"}, nullptr, 0, log);
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  const std::string forged = "2026-01-01T00:00:00.000 critical FORGED";
  for (const std::string& id : {"x\n" + forged + "\x1b[0m", "y\r" + forged, std::string(1 << 20, 'z')}) {
    grpc::ClientContext context;
    v1::RecognizeRequest request;  // no scene: refused, and the refusal is logged with the id
    request.set_request_id(id);
    v1::RecognizeResponse response;
    EXPECT_EQ(stub->Recognize(&context, request, &response).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  }
  ASSERT_EQ(server.terminate(), 0);

  const std::string text = readLog(log);
  EXPECT_NE(text.find("x\\x0a" + forged + "\\x1b[0m"), std::string::npos) << text.substr(0, 4096);
  EXPECT_NE(text.find("y\\x0d" + forged), std::string::npos);
  EXPECT_EQ(text.find('\x1b'), std::string::npos);
  EXPECT_EQ(text.find('\r'), std::string::npos);
  EXPECT_NE(text.find("...(1048576 bytes)"), std::string::npos);
  std::istringstream lines(text);
  int count = 0;
  for (std::string line; std::getline(lines, line); ++count) {
    EXPECT_NE(line.rfind(forged, 0), 0u) << "a forged line: " << line;
    EXPECT_LT(line.size(), 2048u) << line.substr(0, 200);
  }
  EXPECT_GT(count, 3);
}

TEST_F(UntrustedTextServiceTest, ModelNamesAreShortAndPlain) {
  ServerProcess server({"--models", dir_.string()});
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  const auto load = [&](const std::string& name) {
    grpc::ClientContext context;
    v1::LoadModelRequest request;
    request.set_name(name);
    request.set_path("default.ismm");
    v1::ModelInfo info;
    return stub->LoadModel(&context, request, &info);
  };
  for (const std::string name : {std::string(100000, 'n'), std::string(65, 'n'), std::string("two\nlines"),
                                 std::string("a/b"), std::string(".hidden"), std::string("caf\xc3\xa9"),
                                 std::string("sp ace")}) {
    const grpc::Status status = load(name);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << loggable(name, 80);
    EXPECT_NE(status.error_message().find("must be 1 to 64 letters, digits, '.', '_' or '-'"), std::string::npos)
        << status.error_message();
    EXPECT_LE(status.error_message().size(), kMaxStatusMessage + 40);
  }
  EXPECT_TRUE(load(std::string(64, 'n')).ok());
  EXPECT_TRUE(load("chairs_v2.1-test").ok());

  // Asking for a huge unknown name is NOT_FOUND, with the name shortened, not a status too large
  // for gRPC's trailers.
  grpc::ClientContext context;
  v1::GetModelRequest request;
  request.set_name(std::string(100000, 'q'));
  v1::ModelInfo info;
  const grpc::Status status = stub->GetModel(&context, request, &info);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND) << status.error_message().substr(0, 200);
  EXPECT_NE(status.error_message().find("...' (100000 bytes) (loaded: "), std::string::npos)
      << status.error_message().substr(0, 300);
  EXPECT_LE(status.error_message().size(), 512u);
}

TEST_F(UntrustedTextServiceTest, AStatusThatQuotesTheRequestIsCapped) {
  ServerProcess server({"--models", dir_.string()});
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  grpc::ClientContext context;
  v1::RecognizeRequest request;
  *request.mutable_scene() = cloudMessage(smallScene().scene);
  request.mutable_options()->add_categories(std::string(100000, 'c'));  // quoted back by core
  v1::RecognizeResponse response;
  const grpc::Status status = stub->Recognize(&context, request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::NOT_FOUND) << status.error_message().substr(0, 200);
  EXPECT_EQ(status.error_message().rfind("category 'ccc", 0), 0u) << status.error_message().substr(0, 200);
  EXPECT_NE(status.error_message().find("bytes in all)"), std::string::npos);
  EXPECT_LE(status.error_message().size(), kMaxStatusMessage + 40);
}

}  // namespace
}  // namespace ism::testing
