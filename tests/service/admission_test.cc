// Admission control (server/admission.h): what a server takes in at once is bounded, refusals
// come at once with RESOURCE_EXHAUSTED, and the recognizer's health says when it refuses.
#include <gtest/gtest.h>

#include <future>

#include "grpc/health/v1/health.grpc.pb.h"
#include "server/admission.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
using server::Admission;

TEST(Admission, RequestsBeyondTheBoundAreRefusedAndTheRecognizerIsNotServing) {
  server::Health health;
  health.setModels(1);
  Admission admission(100, &health);
  std::unique_ptr<Admission::Ticket> a, b, c;
  ASSERT_TRUE(admission.admit(60, "a", &a).ok());
  const grpc::Status full = admission.admit(50, "b", &b);
  EXPECT_EQ(full.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(full.error_message().find("the server is full"), std::string::npos) << full.error_message();
  EXPECT_EQ(b, nullptr);
  EXPECT_FALSE(health.recognizerServing());
  ASSERT_TRUE(admission.admit(40, "c", &c).ok());  // what fits is still taken
  EXPECT_EQ(admission.held(), 100u);
  c.reset();
  EXPECT_FALSE(health.recognizerServing()) << "serving again only once down to half the bound";
  a.reset();
  EXPECT_TRUE(health.recognizerServing());
  EXPECT_EQ(admission.held(), 0u);

  // Larger than the bound itself: refused, saying that waiting will not help, and the server is not full.
  const grpc::Status never = admission.admit(101, "this request", &b);
  EXPECT_EQ(never.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(never.error_message().find("is larger than the"), std::string::npos) << never.error_message();
  EXPECT_TRUE(health.recognizerServing());

  Admission unbounded(0, nullptr);
  EXPECT_TRUE(unbounded.admit(size_t{1} << 40, "huge", &a).ok());
}

bool recognizerServing(const ServerProcess& server) {
  auto health = grpc::health::v1::Health::NewStub(server.channel());
  grpc::ClientContext context;
  grpc::health::v1::HealthCheckRequest request;
  request.set_service("ism.v1.FurnitureRecognizer");
  grpc::health::v1::HealthCheckResponse response;
  return health->Check(&context, request, &response).ok() &&
         response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
}

TEST(AdmissionService, ARequestLargerThanTheBoundIsRefusedAtOnce) {
  ServerProcess server({"--max-queued-mb", "1"});
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  v1::RecognizeRequest request;
  request.mutable_scene()->mutable_cloud()->set_xyz(std::string(1'500'000 - 1'500'000 % 12, '\0'));
  grpc::ClientContext context;
  v1::RecognizeResponse response;
  const grpc::Status status = stub->Recognize(&context, request, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
  EXPECT_NE(status.error_message().find("this request of 1.4 MB is larger than the 1.0 MB of requests this server "
                                        "holds at once (--max-queued-mb)"),
            std::string::npos)
      << status.error_message();
  EXPECT_TRUE(recognizerServing(server));
}

// In a stream, a frame that can never fit fails alone, and the stream goes on.
TEST(AdmissionService, AStreamFrameLargerThanTheBoundFailsAlone) {
  ServerProcess server({"--max-queued-mb", "1"});
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(2));
  auto stream = stub->StreamFrames(&context);
  v1::StreamFramesRequest large, small;
  large.set_frame_id(1);
  large.mutable_scene()->mutable_cloud()->set_xyz(std::string(1'500'000 - 1'500'000 % 12, '\0'));
  small.set_frame_id(2);
  *small.mutable_scene() = cloudMessage(smallScene().scene);
  ASSERT_TRUE(stream->Write(large));
  ASSERT_TRUE(stream->Write(small));
  stream->WritesDone();
  std::vector<v1::FrameResult> results;
  for (v1::FrameResult result; stream->Read(&result);) results.push_back(result);
  ASSERT_TRUE(stream->Finish().ok());
  ASSERT_EQ(results.size(), 2u);
  ASSERT_TRUE(results[0].has_error());
  EXPECT_EQ(results[0].error().code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(results[0].error().message().find("this frame of 1.4 MB is larger than the 1.0 MB"), std::string::npos)
      << results[0].error().message();
  EXPECT_TRUE(results[1].has_result()) << results[1].error().message();
}

// A burst larger than the bound: each request is served or refused at once, never anything else,
// and afterwards everything held is given back (the next request is served, health says so).
TEST(AdmissionService, ABurstIsServedOrRefusedAndLeavesNothingHeld) {
  ServerProcess server({"--max-queued-mb", "1", "--threads", "1"});
  const v1::Scene scene = cloudMessage(smallScene().scene);
  ASSERT_GT(scene.ByteSizeLong(), 120'000u);  // ten of them are more than the 1 MB bound
  std::vector<std::future<grpc::Status>> calls;
  for (int i = 0; i < 10; ++i) {
    calls.push_back(std::async(std::launch::async, [&] {
      auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
      v1::RecognizeRequest request;
      *request.mutable_scene() = scene;
      grpc::ClientContext context;
      context.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(5));
      // Each call has a channel of its own, and gRPC 1.51's first connection attempt sometimes
      // fails at once (UNAVAILABLE, as in faults_test.cc): the server surely runs, so each call
      // waits for its connection, and what it gets back is the server's answer.
      context.set_wait_for_ready(true);
      v1::RecognizeResponse response;
      return stub->Recognize(&context, request, &response);
    }));
  }
  for (auto& call : calls) {
    const grpc::Status status = call.get();
    if (status.ok()) continue;
    EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << status.error_message();
    EXPECT_NE(status.error_message().find("the server is full"), std::string::npos) << status.error_message();
  }
  EXPECT_TRUE(recognizerServing(server));
  auto stub = v1::FurnitureRecognizer::NewStub(server.channel());
  v1::RecognizeRequest request;
  *request.mutable_scene() = scene;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(2));
  context.set_wait_for_ready(true);
  v1::RecognizeResponse response;
  EXPECT_TRUE(stub->Recognize(&context, request, &response).ok());
}

}  // namespace
}  // namespace ism::testing
