// The /metrics endpoint's address: it listens on gRPC's host unless told otherwise, and a
// server that cannot take its address says which.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "server/options.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;

TEST(MetricsEndpoint, AnAddressWithoutHostTakesTheGrpcHost) {
  using server::metricsAddress;
  EXPECT_EQ(metricsAddress("127.0.0.1:50051", ":9464"), "127.0.0.1:9464");
  EXPECT_EQ(metricsAddress("0.0.0.0:50051", ":9464"), "0.0.0.0:9464");
  EXPECT_EQ(metricsAddress("[::1]:50051", ":9464"), "[::1]:9464");
  EXPECT_EQ(metricsAddress("localhost:50051", ":9464"), "127.0.0.1:9464");
  EXPECT_EQ(metricsAddress("unix:/run/ism.sock", ":9464"), "127.0.0.1:9464");
  EXPECT_EQ(metricsAddress("127.0.0.1:50051", "10.1.2.3:9999"), "10.1.2.3:9999");
  EXPECT_EQ(metricsAddress("127.0.0.1:50051", ""), "");
  EXPECT_EQ(server::ServerOptions{}.metrics_listen, ":9464");
}

TEST(MetricsEndpoint, ServedOnTheGrpcHostWhenNoneIsGiven) {
  const int port = freePort();
  ServerProcess server({"--metrics-listen", ":" + std::to_string(port)});
  EXPECT_NE(server.metrics().find("ism_loaded_models"), std::string::npos);
}

TEST(MetricsEndpoint, AnAddressInUseIsNamed) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(listen(fd, 1), 0);
  socklen_t length = sizeof address;
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  const std::string taken = "127.0.0.1:" + std::to_string(ntohs(address.sin_port));

  const std::string log =
      (fs::path(::testing::TempDir()) / ("ism_metrics_test_" + std::to_string(getpid()) + ".log")).string();
  EXPECT_THROW(ServerProcess({"--metrics-listen", taken}, nullptr, 0, log), std::runtime_error);
  close(fd);
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("cannot serve /metrics on " + taken + " (--metrics-listen): the port is taken"),
            std::string::npos)
      << text.str();
  fs::remove(log);
}

int connectTo(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

// Twenty connections that never send a request used to hold civetweb's two threads for 30 s
// each, so that a scrape behind them waited minutes. The patience given here is far beyond what
// the bounded server needs (a few seconds) and far below what the unbounded one took.
TEST(MetricsEndpoint, IdleConnectionsDoNotStarveAScrape) {
  ServerProcess server;
  std::vector<int> idle;
  for (int i = 0; i < 20; ++i) idle.push_back(connectTo(server.metricsPort()));
  const int fd = connectTo(server.metricsPort());
  ASSERT_GE(fd, 0);
  timeval patience{60, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &patience, sizeof patience);
  const std::string request = "GET /metrics HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  ASSERT_EQ(write(fd, request.data(), request.size()), static_cast<ssize_t>(request.size()));
  std::string response;
  char buffer[4096];
  for (ssize_t n; (n = read(fd, buffer, sizeof buffer)) > 0;) response.append(buffer, static_cast<size_t>(n));
  close(fd);
  for (int other : idle) close(other);
  EXPECT_NE(response.find("ism_loaded_models"), std::string::npos) << response.substr(0, 200);
}

}  // namespace
}  // namespace ism::testing
