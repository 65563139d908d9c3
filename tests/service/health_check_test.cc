// `ism-server --health-check`, the image's HEALTHCHECK: it finds the server its options describe
// and exits 0 only for SERVING, naming the address and the status otherwise.
#include <gtest/gtest.h>

#include "server/health_probe.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {

TEST(HealthCheck, WildcardHostsAreProbedOnLoopback) {
  using server::probeAddress;
  EXPECT_EQ(probeAddress("0.0.0.0:50051"), "127.0.0.1:50051");
  EXPECT_EQ(probeAddress(":50051"), "127.0.0.1:50051");
  EXPECT_EQ(probeAddress("[::]:50051"), "[::1]:50051");
  EXPECT_EQ(probeAddress("127.0.0.1:7000"), "127.0.0.1:7000");
  EXPECT_EQ(probeAddress("10.1.2.3:50051"), "10.1.2.3:50051");
  EXPECT_EQ(probeAddress("unix:/run/ism.sock"), "unix:/run/ism.sock");
}

TEST(HealthCheck, ARunningServerIsServing) {
  ServerProcess server;
  int code = 0;
  const std::string out = runCommand(std::string(ISM_SERVER_BINARY) + " --health-check --listen " + server.address(), &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out, "SERVING\n");
}

TEST(HealthCheck, TheListenVariableIsFollowed) {
  ServerProcess server;
  int code = 0;
  const std::string out = runCommand(
      "ISM_LISTEN=0.0.0.0:" + std::to_string(server.port()) + " " + ISM_SERVER_BINARY + " --health-check", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out, "SERVING\n");
}

TEST(HealthCheck, NoServerFailsAndSaysWhere) {
  const std::string address = "127.0.0.1:" + std::to_string(freePort());
  int code = 0;
  const std::string out = runCommand(std::string(ISM_SERVER_BINARY) + " --health-check --listen " + address, &code);
  EXPECT_EQ(code, 1) << out;
  EXPECT_NE(out.find("health check of " + address + " failed: UNAVAILABLE"), std::string::npos) << out;
}

}  // namespace
}  // namespace ism::testing
