// `ism-client bench` against the real ism-server on 127.0.0.1: counts, bounds, latency order,
// errors by status and exit codes (0 all OK, 2 usage, 10 + the most common error's status).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/io/cloud_io.h"
#include "core/io/file_bytes.h"
#include "tests/service/service_fixture.h"

namespace ism::testing {
namespace {
namespace fs = std::filesystem;

class BenchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_ = new ServerProcess();
    dir_ = fs::path(::testing::TempDir()) / ("ism_bench_test_" + std::to_string(getpid()));
    fs::create_directories(dir_);
    savePcd(smallScene(0).scene, (dir_ / "scene0.pcd").string());
    savePcd(smallScene(3).scene, (dir_ / "scene3.pcd").string());
    writeFileBytes((dir_ / "broken.png").string(), "this is not a PNG");
  }
  static void TearDownTestSuite() {
    delete server_;
    fs::remove_all(dir_);
  }

  static std::string scenes() { return (dir_ / "scene0.pcd").string() + " " + (dir_ / "scene3.pcd").string(); }

  // Runs the client against `server` and parses its JSON report; fails the test when there is none.
  // Ordered: the report lists server stages in pipeline order.
  static nlohmann::ordered_json bench(const std::string& arguments, int* exit_code, const std::string& server = "") {
    const std::string output = runCommand(std::string(ISM_CLIENT_BINARY) + " --server " +
                                              (server.empty() ? server_->address() : server) + " --json bench " +
                                              arguments,
                                          exit_code);
    const auto line = output.rfind("{\"call\"");
    EXPECT_NE(line, std::string::npos) << output;
    if (line == std::string::npos) return nlohmann::ordered_json::object();
    return nlohmann::ordered_json::parse(output.substr(line));
  }

  static void expectSaneLatency(const nlohmann::ordered_json& report) {
    const auto& l = report.at("latency_ms");
    EXPECT_GT(l.at("p50").get<double>(), 0.0) << report;
    EXPECT_LE(l.at("p50").get<double>(), l.at("p90").get<double>()) << report;
    EXPECT_LE(l.at("p90").get<double>(), l.at("p99").get<double>()) << report;
    EXPECT_LE(l.at("p99").get<double>(), l.at("max").get<double>()) << report;
    EXPECT_LE(l.at("mean").get<double>(), l.at("max").get<double>()) << report;
    EXPECT_GT(report.at("throughput_rps").get<double>(), 0.0) << report;
  }

  static ServerProcess* server_;
  static fs::path dir_;
};
ServerProcess* BenchTest::server_ = nullptr;
fs::path BenchTest::dir_;

TEST_F(BenchTest, ClosedLoopSendsExactlyTheRequestedCount) {
  int code = -1;
  const auto report = bench("--requests 20 --concurrency 2 --warmup 2 " + scenes(), &code);
  EXPECT_EQ(code, 0) << report;
  EXPECT_EQ(report.at("call"), "Recognize");
  EXPECT_EQ(report.at("loop"), "closed");
  EXPECT_EQ(report.at("requests"), 20) << report;
  EXPECT_EQ(report.at("ok"), 20) << report;
  EXPECT_TRUE(report.at("errors").empty()) << report;
  expectSaneLatency(report);
  // The server's own timings come back with every response; the pipeline starts by decoding.
  ASSERT_FALSE(report.at("server_stage_median_ms").empty()) << report;
  EXPECT_EQ(report.at("server_stage_median_ms").begin().key(), "decode") << report;
  // Two workers each wait for their answer: the run cannot be faster than ten sequential calls.
  EXPECT_GE(report.at("elapsed_s").get<double>() * 1000.0, 10 * report.at("latency_ms").at("p50").get<double>() * 0.5)
      << report;
}

TEST_F(BenchTest, OpenLoopIsBoundedByTheDuration) {
  int code = -1;
  const auto start = std::chrono::steady_clock::now();
  const auto report = bench("--rate 20 --duration 1s --concurrency 4 " + scenes(), &code);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(code, 0) << report;
  EXPECT_EQ(report.at("loop"), "open");
  // Slots every 50 ms from 0 to 950 ms; none is scheduled at or after the end.
  EXPECT_EQ(report.at("requests"), 20) << report;
  EXPECT_EQ(report.at("ok"), 20) << report;
  expectSaneLatency(report);
  EXPECT_LT(wall_s, 15.0);  // the duration plus draining, not a run to a request count
}

TEST_F(BenchTest, DurationStopsAClosedLoopBeforeItsCount) {
  int code = -1;
  const auto start = std::chrono::steady_clock::now();
  const auto report = bench("--requests 1000000 --duration 500ms --concurrency 2 " + scenes(), &code);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(code, 0) << report;
  EXPECT_GT(report.at("requests").get<uint64_t>(), 0u) << report;
  EXPECT_LT(report.at("requests").get<uint64_t>(), 1000000u) << report;
  EXPECT_EQ(report.at("ok"), report.at("requests")) << report;
  EXPECT_LT(wall_s, 15.0);
}

TEST_F(BenchTest, StreamAnswersEveryFrame) {
  int code = -1;
  auto report = bench("--stream --requests 12 --concurrency 2 " + scenes(), &code);
  EXPECT_EQ(code, 0) << report;
  EXPECT_EQ(report.at("call"), "StreamFrames");
  EXPECT_EQ(report.at("requests"), 12) << report;
  EXPECT_EQ(report.at("ok"), 12) << report;
  expectSaneLatency(report);
  // Open loop writes frames without waiting for answers: several are in flight on one stream.
  report = bench("--stream --rate 25 --requests 8 --concurrency 1 " + scenes(), &code);
  EXPECT_EQ(code, 0) << report;
  EXPECT_EQ(report.at("ok"), 8) << report;
  expectSaneLatency(report);
}

TEST_F(BenchTest, TablePrintsThroughputAndPercentiles) {
  int code = -1;
  const std::string out = runCommand(std::string(ISM_CLIENT_BINARY) + " --server " + server_->address() +
                                         " bench -n 4 -c 2 " + scenes(),
                                     &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("bench: Recognize, closed loop, 2 workers, 2 file(s)"), std::string::npos) << out;
  EXPECT_NE(out.find("  ok          4\n"), std::string::npos) << out;
  EXPECT_NE(out.find("throughput"), std::string::npos) << out;
  EXPECT_NE(out.find("p99"), std::string::npos) << out;
  EXPECT_NE(out.find("server stages (median ms): decode"), std::string::npos) << out;
}

TEST_F(BenchTest, UnreachableServerCountsUnavailable) {
  int code = -1;
  // Port 1 on loopback: nothing listens there without root, so connections are refused at once.
  auto report = bench("--requests 5 --concurrency 2 " + scenes(), &code, "127.0.0.1:1");
  EXPECT_EQ(code, 10 + 14) << report;
  EXPECT_EQ(report.at("ok"), 0) << report;
  EXPECT_EQ(report.at("errors").at("UNAVAILABLE"), 5) << report;
  report = bench("--stream --requests 3 --concurrency 1 " + scenes(), &code, "127.0.0.1:1");
  EXPECT_EQ(code, 10 + 14) << report;
  EXPECT_EQ(report.at("errors").at("UNAVAILABLE"), 3) << report;
}

TEST_F(BenchTest, BadInputIsReportedByStatus) {
  int code = -1;
  // The client sends PNG bytes as they are: the server refuses them, request by request.
  const auto report = bench("--requests 6 --concurrency 2 " + (dir_ / "broken.png").string() + " " +
                                (dir_ / "scene0.pcd").string(),
                            &code);
  EXPECT_EQ(code, 10 + 3) << report;
  EXPECT_EQ(report.at("requests"), 6) << report;
  EXPECT_EQ(report.at("ok"), 3) << report;
  EXPECT_EQ(report.at("errors").at("INVALID_ARGUMENT"), 3) << report;
  // A file the client cannot read at all fails before anything is sent.
  const std::string out =
      runCommand(std::string(ISM_CLIENT_BINARY) + " --server " + server_->address() + " bench " +
                     (dir_ / "missing.pcd").string(),
                 &code);
  EXPECT_EQ(code, 1) << out;
}

TEST_F(BenchTest, LimitsAreUsageErrors) {
  const std::string client = std::string(ISM_CLIENT_BINARY) + " --server " + server_->address() + " bench ";
  const std::string pcd = " " + (dir_ / "scene0.pcd").string();
  for (const std::string arguments : {"--requests 1000001", "--requests 0", "--duration 2h", "--duration 3601",
                                      "--duration 10parsecs", "--concurrency 0", "--rate 0", "--rate -5"}) {
    int code = -1;
    const std::string out = runCommand(client + arguments + pcd, &code);
    EXPECT_EQ(code, 2) << arguments << ": " << out;
  }
  int code = -1;
  const std::string out = runCommand(client + "--requests 3", &code);  // no file
  EXPECT_EQ(code, 2) << out;
}

}  // namespace
}  // namespace ism::testing
