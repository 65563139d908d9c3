#pragma once
// `ism-client bench`: a bounded load generator in the style of ghz. Closed loop (each worker
// sends its next request when the previous one answered) or open loop (sends scheduled at a
// target rate, latency measured from the scheduled time so that a slow server cannot hide its
// queueing: no coordinated omission). Unary Recognize calls or frames on StreamFrames calls.
#include <cstdint>
#include <map>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "client/cli/common.h"

namespace ism::client {

constexpr uint64_t kMaxBenchRequests = 1000000;
constexpr double kMaxBenchSeconds = 3600;
constexpr unsigned kMaxBenchConcurrency = 1000;

struct BenchParams {
  std::vector<std::string> files;  // requests cycle through them
  unsigned concurrency = 4;        // workers (unary) or concurrent streams (--stream)
  uint64_t requests = 0;           // 0: as many as fit in the duration
  double duration_s = 0;           // 0: until `requests` are done, but never beyond kMaxBenchSeconds
  double rate = 0;                 // requests/s scheduled (open loop); 0: closed loop
  bool stream = false;
  uint64_t warmup = 0;  // closed-loop requests sent first and not counted

  void add(CLI::App* app);  // the subcommand's options, with the hard limits as checks
};

struct BenchReport {
  BenchParams params;
  uint64_t requests = 0;  // completed, successfully or not
  uint64_t ok = 0;
  uint64_t late = 0;  // open loop: sent more than kLateAfter after their scheduled time
  std::map<grpc::StatusCode, uint64_t> errors;
  double elapsed_s = 0;  // first scheduled send to last completion
  // Of the successful requests, in ms; all zero when none succeeded.
  double mean_ms = 0, p50_ms = 0, p90_ms = 0, p99_ms = 0, max_ms = 0;
  std::vector<std::pair<std::string, double>> stage_median_ms;  // server timings, pipeline order

  double throughput() const { return elapsed_s > 0 ? static_cast<double>(requests) / elapsed_s : 0.0; }
};

// Warm-up, then the measured run. Input files are read once, before any request is sent.
BenchReport runBench(const Connection& connection, const BenchParams& params, const RecognitionFlags& flags);

void printBenchTable(std::ostream& out, const BenchReport& report);
std::string benchJson(const BenchReport& report);  // one line
// 0 when every request succeeded, else kStatusBase + the most common error's status code.
int benchExitCode(const BenchReport& report);

}  // namespace ism::client
