#include "client/cli/bench.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <iomanip>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "ism/v1/service.grpc.pb.h"

namespace ism::client {
namespace {

using Clock = std::chrono::steady_clock;
using Stub = v1::FurnitureRecognizer::Stub;

// A send that starts this much after its slot is late: every worker was still busy. Above the
// wake-up jitter of a sleeping thread on a loaded machine, far below a recognition.
constexpr auto kLateAfter = std::chrono::milliseconds(1);
// Calls still running when the duration is over get this long to answer, then are cancelled
// (DEADLINE_EXCEEDED), so that a hung server cannot keep the bench running.
constexpr auto kDrain = std::chrono::seconds(10);

struct Slot {
  uint64_t index;
  Clock::time_point due;  // open loop: the scheduled time; closed loop: when it was claimed
};

// Hands out request slots to the workers until the count or the time is used up.
class Schedule {
 public:
  Schedule(uint64_t requests, double duration_s, double rate)
      : limit_(requests),
        rate_(rate),
        start_(Clock::now()),
        end_(start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration_s))) {}

  // Open loop: sleeps until the slot is due, so that a slot's latency counts from its schedule.
  std::optional<Slot> claim() {
    const uint64_t index = next_++;
    if (limit_ > 0 && index >= limit_) return std::nullopt;
    if (rate_ <= 0) {
      const auto now = Clock::now();
      if (now >= end_) return std::nullopt;
      return Slot{index, now};
    }
    const auto due =
        start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(index / rate_));
    if (due >= end_) return std::nullopt;
    std::this_thread::sleep_until(due);
    return Slot{index, due};
  }

  Clock::time_point start() const { return start_; }
  Clock::time_point end() const { return end_; }

 private:
  std::atomic<uint64_t> next_{0};
  const uint64_t limit_;
  const double rate_;
  const Clock::time_point start_, end_;
};

// What the workers measured, shared between them.
class Recorder {
 public:
  void record(const Slot& slot, Clock::time_point sent, grpc::StatusCode code, const v1::RecognitionResult* result) {
    const auto done = Clock::now();
    std::lock_guard<std::mutex> lock(mutex_);
    last_ = std::max(last_, done);
    if (sent - slot.due > kLateAfter) ++late_;
    if (code != grpc::StatusCode::OK) {
      ++errors_[code];
      return;
    }
    latencies_ms_.push_back(std::chrono::duration<double, std::milli>(done - slot.due).count());
    if (result == nullptr) return;
    for (const auto& timing : result->timings()) {
      auto stage = std::find_if(stages_.begin(), stages_.end(), [&](const auto& s) { return s.first == timing.stage(); });
      if (stage == stages_.end()) stage = stages_.insert(stages_.end(), {timing.stage(), {}});
      stage->second.push_back(timing.ms());
    }
  }

  void fill(BenchReport* report, Clock::time_point start) {
    std::lock_guard<std::mutex> lock(mutex_);
    report->ok = latencies_ms_.size();
    report->errors = errors_;
    report->requests = report->ok;
    for (const auto& [code, count] : errors_) report->requests += count;
    report->late = report->params.rate > 0 ? late_ : 0;
    report->elapsed_s = report->requests > 0 ? std::chrono::duration<double>(last_ - start).count() : 0.0;
    if (!latencies_ms_.empty()) {
      std::vector<double>& l = latencies_ms_;
      std::sort(l.begin(), l.end());
      double sum = 0;
      for (double v : l) sum += v;
      report->mean_ms = sum / static_cast<double>(l.size());
      report->p50_ms = percentile(l, 0.50);
      report->p90_ms = percentile(l, 0.90);
      report->p99_ms = percentile(l, 0.99);
      report->max_ms = l.back();
    }
    for (auto& [stage, values] : stages_) {
      std::sort(values.begin(), values.end());
      report->stage_median_ms.emplace_back(stage, percentile(values, 0.5));
    }
  }

 private:
  // Nearest rank on sorted values: always one of the measured values.
  static double percentile(const std::vector<double>& sorted, double p) {
    const auto rank = static_cast<size_t>(std::ceil(p * static_cast<double>(sorted.size())));
    return sorted[std::max<size_t>(rank, 1) - 1];
  }

  std::mutex mutex_;
  Clock::time_point last_{};
  uint64_t late_ = 0;
  std::map<grpc::StatusCode, uint64_t> errors_;
  std::vector<double> latencies_ms_;
  std::vector<std::pair<std::string, std::vector<double>>> stages_;
};

struct Run {
  const Connection& connection;
  Stub& stub;
  const std::vector<v1::RecognizeRequest>& requests;  // built before the clock starts
  Schedule& schedule;
  Recorder& recorder;
  bool open_loop;
  std::chrono::system_clock::time_point hard_deadline;  // the end of the duration plus kDrain

  void prepare(grpc::ClientContext* context) const {
    connection.prepare(context);
    if (context->deadline() > hard_deadline) context->set_deadline(hard_deadline);
  }

  void unaryWorker() const {
    while (const auto slot = schedule.claim()) {
      grpc::ClientContext context;
      prepare(&context);
      v1::RecognizeResponse response;
      const auto sent = Clock::now();
      const grpc::Status status = stub.Recognize(&context, requests[slot->index % requests.size()], &response);
      recorder.record(*slot, sent, status.error_code(), &response.result());
    }
  }

  // One StreamFrames call after another (a broken call fails its unanswered frames and the worker
  // opens the next). Closed loop keeps one frame in flight per stream; open loop writes each
  // frame when it is due, and gRPC flow control holding a write back shows as late sends.
  void streamWorker() const {
    for (;;) {
      grpc::ClientContext context;
      prepare(&context);
      auto call = stub.StreamFrames(&context);
      std::mutex mutex;
      std::condition_variable answered;
      std::map<uint64_t, std::pair<Slot, Clock::time_point>> in_flight;  // by frame_id
      bool reading = true;
      std::thread reader([&] {
        v1::FrameResult result;
        while (call->Read(&result)) {
          std::lock_guard<std::mutex> lock(mutex);
          const auto frame = in_flight.find(result.frame_id());
          if (frame == in_flight.end()) continue;  // an id we never sent: nothing to time
          const auto code = result.has_error() ? static_cast<grpc::StatusCode>(result.error().code())
                                               : grpc::StatusCode::OK;
          recorder.record(frame->second.first, frame->second.second, code, &result.result());
          in_flight.erase(frame);
          answered.notify_all();
        }
        std::lock_guard<std::mutex> lock(mutex);
        reading = false;
        answered.notify_all();
      });

      v1::StreamFramesRequest request;
      request.mutable_settings()->set_policy(v1::BACKPRESSURE_POLICY_EVERY_FRAME);
      *request.mutable_settings()->mutable_options() = requests.front().options();
      bool exhausted = false;
      for (;;) {
        if (!open_loop) {
          // A call that is over still takes the next slot: its write fails and the frame counts
          // as an error, so that a refusing server cannot make this loop spin without bound.
          std::unique_lock<std::mutex> lock(mutex);
          answered.wait(lock, [&] { return in_flight.empty() || !reading; });
        }
        const auto slot = schedule.claim();
        if (!slot) {
          exhausted = true;
          break;
        }
        // Sent from here: copying the scene into the message is part of sending it.
        const auto sent = Clock::now();
        request.set_frame_id(slot->index + 1);
        *request.mutable_scene() = requests[slot->index % requests.size()].scene();
        {
          std::lock_guard<std::mutex> lock(mutex);
          in_flight.emplace(request.frame_id(), std::make_pair(*slot, sent));
        }
        if (!call->Write(request)) break;  // the call is over; Finish says why
        request.clear_settings();
      }
      call->WritesDone();
      reader.join();
      const grpc::Status status = call->Finish();
      // A call that ended cleanly yet left frames unanswered broke the protocol.
      const grpc::StatusCode code = status.ok() ? grpc::StatusCode::INTERNAL : status.error_code();
      for (const auto& [id, frame] : in_flight) recorder.record(frame.first, frame.second, code, nullptr);
      if (exhausted) return;
    }
  }
};

void runOnce(const Connection& connection, Stub& stub, const std::vector<v1::RecognizeRequest>& requests,
             const BenchParams& params, BenchReport* report) {
  const double duration_s = params.duration_s > 0 ? params.duration_s : kMaxBenchSeconds;
  Schedule schedule(params.requests, duration_s, params.rate);
  Recorder recorder;
  const auto hard_deadline = std::chrono::system_clock::now() +
                             std::chrono::duration_cast<std::chrono::system_clock::duration>(
                                 std::chrono::duration<double>(duration_s)) +
                             kDrain;
  const Run run{connection, stub, requests, schedule, recorder, params.rate > 0, hard_deadline};
  std::vector<std::thread> workers;
  for (unsigned i = 0; i < params.concurrency; ++i) {
    workers.emplace_back([&run, stream = params.stream] { stream ? run.streamWorker() : run.unaryWorker(); });
  }
  for (auto& worker : workers) worker.join();
  if (report != nullptr) recorder.fill(report, schedule.start());
}

std::string loopName(const BenchParams& params) {
  if (params.rate <= 0) return "closed loop";
  std::ostringstream s;
  s << "open loop at " << params.rate << " req/s";
  return s.str();
}

}  // namespace

void BenchParams::add(CLI::App* app) {
  app->add_option("files", files, "scene files (.pcd, .ply, .png), sent in turn")->required();
  app->add_option("--concurrency,-c", concurrency, "workers (unary) or concurrent streams (--stream)")
      ->check(CLI::Range(1u, kMaxBenchConcurrency))
      ->capture_default_str();
  auto* count = app->add_option("--requests,-n", requests, "requests to send (at most 1e6; without -n or -z: 200)")
                    ->check(CLI::Range(uint64_t{1}, kMaxBenchRequests));
  app->add_option("--duration,-z", duration_s, "stop sending after this long: 500ms, 10s, 2m (at most 1h)")
      ->transform(CLI::AsNumberWithUnit(std::map<std::string, double>{{"ms", 1e-3}, {"s", 1}, {"m", 60}, {"h", 3600}},
                                        CLI::AsNumberWithUnit::CASE_SENSITIVE))
      ->check(CLI::Range(1e-3, kMaxBenchSeconds));
  app->add_option("--rate,-r", rate, "open loop: requests per second, scheduled (default: closed loop)")
      ->check(CLI::Range(1e-3, 1e6));
  app->add_flag("--stream", stream, "send frames on --concurrency StreamFrames calls instead of Recognize calls");
  app->add_option("--warmup", warmup, "closed-loop requests sent first and not counted")
      ->check(CLI::Range(uint64_t{0}, kMaxBenchRequests));
  // Without a bound a closed loop would run for the full hour: ghz's default count.
  app->callback([this, count] {
    if (count->count() == 0 && duration_s <= 0) requests = 200;
  });
}

BenchReport runBench(const Connection& connection, const BenchParams& params, const RecognitionFlags& flags) {
  std::vector<v1::RecognizeRequest> requests(params.files.size());
  for (size_t i = 0; i < params.files.size(); ++i) {
    *requests[i].mutable_scene() = sceneFromFile(params.files[i], flags.intrinsics, false).message;
    flags.applyTo(requests[i].mutable_scene());
    *requests[i].mutable_options() = flags.build();
  }
  auto stub = v1::FurnitureRecognizer::NewStub(connection.channel());
  if (params.warmup > 0) {
    BenchParams warmup = params;
    warmup.requests = params.warmup;
    warmup.rate = 0;
    runOnce(connection, *stub, requests, warmup, nullptr);
  }
  BenchReport report;
  report.params = params;
  runOnce(connection, *stub, requests, params, &report);
  return report;
}

void printBenchTable(std::ostream& out, const BenchReport& report) {
  const BenchParams& p = report.params;
  out << "bench: " << (p.stream ? "StreamFrames" : "Recognize") << ", " << loopName(p) << ", "
      << p.concurrency << (p.stream ? " stream" : " worker") << (p.concurrency == 1 ? "" : "s") << ", " << p.files.size() << " file(s)\n"
      << std::fixed << std::setprecision(2) << "  requests    " << report.requests << "\n"
      << "  ok          " << report.ok << "\n";
  for (const auto& [code, count] : report.errors) out << "  " << std::left << std::setw(12) << statusName(code) << count << "\n";
  if (p.rate > 0) out << "  late        " << report.late << " (sent > 1 ms after schedule)\n";
  out << "  elapsed     " << report.elapsed_s << " s\n"
      << "  throughput  " << report.throughput() << " req/s\n"
      << "latency (ms, successful requests" << (p.rate > 0 ? ", from the scheduled send" : "") << ")\n"
      << std::right << std::setw(10) << "mean" << std::setw(10) << "p50" << std::setw(10) << "p90" << std::setw(10)
      << "p99" << std::setw(10) << "max" << "\n"
      << std::setw(10) << report.mean_ms << std::setw(10) << report.p50_ms << std::setw(10) << report.p90_ms
      << std::setw(10) << report.p99_ms << std::setw(10) << report.max_ms << "\n";
  if (!report.stage_median_ms.empty()) {
    out << "server stages (median ms):";
    for (const auto& [stage, ms] : report.stage_median_ms) out << " " << stage << " " << ms;
    out << "\n";
  }
}

std::string benchJson(const BenchReport& report) {
  const BenchParams& p = report.params;
  nlohmann::ordered_json errors = nlohmann::ordered_json::object();
  for (const auto& [code, count] : report.errors) errors[statusName(code)] = count;
  nlohmann::ordered_json stages = nlohmann::ordered_json::object();
  for (const auto& [stage, ms] : report.stage_median_ms) stages[stage] = ms;
  const nlohmann::ordered_json json = {
      {"call", p.stream ? "StreamFrames" : "Recognize"},
      {"loop", p.rate > 0 ? "open" : "closed"},
      {"rate", p.rate},
      {"concurrency", p.concurrency},
      {"files", p.files.size()},
      {"requests", report.requests},
      {"ok", report.ok},
      {"errors", errors},
      {"late", report.late},
      {"elapsed_s", report.elapsed_s},
      {"throughput_rps", report.throughput()},
      {"latency_ms",
       {{"mean", report.mean_ms},
        {"p50", report.p50_ms},
        {"p90", report.p90_ms},
        {"p99", report.p99_ms},
        {"max", report.max_ms}}},
      {"server_stage_median_ms", stages}};
  return json.dump();
}

int benchExitCode(const BenchReport& report) {
  if (report.errors.empty()) return 0;
  const auto most = std::max_element(report.errors.begin(), report.errors.end(),
                                     [](const auto& a, const auto& b) { return a.second < b.second; });
  return kStatusBase + most->first;
}

}  // namespace ism::client
