// ism-client: command-line client of the furniture recognition service.
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>

#include "client/cli/bench.h"
#include "client/cli/common.h"
#include "client/cli/frame_source.h"
#include "client/cli/output.h"
#include "core/report/report.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "ism/v1/service.grpc.pb.h"
#include "proto/wire/messages.h"

namespace {

using ism::v1::FurnitureRecognizer;
using ism::client::Connection;
using ism::client::FileScene;
using ism::client::kLocalFailure;
using ism::client::kStatusBase;
using ism::client::kUsageError;
using ism::client::RecognitionFlags;
using ism::client::sceneFromFile;
using ism::client::statusName;

const char* kExitCodes = R"(Exit codes:
  0   success
  1   local failure: unreadable input file, no sensor attached
  2   usage error
  10+ the server's gRPC status code: 11 CANCELLED, 13 INVALID_ARGUMENT,
      14 DEADLINE_EXCEEDED, 15 NOT_FOUND, 18 RESOURCE_EXHAUSTED, 19 FAILED_PRECONDITION,
      23 INTERNAL, 24 UNAVAILABLE (server unreachable or not serving)
Environment: ISM_SERVER sets --server.)";

int fail(const std::string& what, const grpc::Status& status) {
  std::cerr << "error: " << what << ": " << statusName(status.error_code()) << ": "
            << status.error_message() << "\n";
  return kStatusBase + status.error_code();
}

// One file: PATH as given. Several: PATH's stem + "_" + the scene's stem, so none overwrites another.
std::string picturePath(const std::string& picture, const std::string& file, size_t files) {
  if (files == 1) return picture;
  const std::filesystem::path p(picture);
  return (p.parent_path() / (p.stem().string() + "_" + std::filesystem::path(file).stem().string() + ".png")).string();
}

int runRecognize(const Connection& connection, const std::vector<std::string>& files, const RecognitionFlags& flags,
                 const std::string& picture) {
  auto stub = FurnitureRecognizer::NewStub(connection.channel());
  int exit_code = 0;
  for (const auto& file : files) {
    ism::v1::RecognizeRequest request;
    FileScene scene;
    try {
      scene = sceneFromFile(file, flags.intrinsics, !picture.empty());
      *request.mutable_scene() = std::move(scene.message);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
      if (exit_code == 0) exit_code = kLocalFailure;
      continue;
    }
    *request.mutable_options() = flags.build();
    grpc::ClientContext context;
    connection.prepare(&context);
    ism::v1::RecognizeResponse response;
    const grpc::Status status = stub->Recognize(&context, request, &response);
    if (!status.ok()) {
      const int code = fail(file, status);
      if (exit_code == 0) exit_code = code;
      continue;
    }
    if (connection.json) {
      std::cout << "{\"file\":\"" << file << "\",\"response\":" << ism::client::toJson(response) << "}\n";
    } else {
      ism::client::printResult(std::cout, file, response.result());
    }
    if (!picture.empty()) {
      const std::string path = picturePath(picture, file, files.size());
      try {
        ism::savePicture(scene.scene, ism::wire::resultFromProto(response.result()).hypotheses, path, scene.camera);
      } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << "\n";
        if (exit_code == 0) exit_code = kLocalFailure;
      }
    }
  }
  return exit_code;
}

// A frame sent on a stream and not answered yet: sent again after a reconnection.
struct SentFrame {
  int64_t timestamp_us = 0;
  ism::v1::Scene scene;
};

constexpr auto kFirstReconnectDelay = std::chrono::milliseconds(250);
constexpr auto kMaxReconnectDelay = std::chrono::seconds(8);

// Streams frames; when the stream breaks with UNAVAILABLE (server restarted, crashed, or shut down
// for an update), opens a new one after a growing delay, sends the frames that had no result yet
// and goes on with the source. Gives up after `reconnect_attempts` failures in a row.
int runStream(const Connection& connection, std::unique_ptr<ism::client::FrameSource> source,
              const RecognitionFlags& flags, bool latest_wins, uint64_t max_frames, int reconnect_attempts) {
  std::cerr << "streaming " << source->describe() << " (" << (latest_wins ? "latest frame wins" : "every frame")
            << ")\n";
  std::mutex mutex;  // guards what follows, shared by the writer and the reader
  std::map<uint64_t, SentFrame> unanswered;  // by frame id
  uint64_t taken = 0;                        // frames taken from the source so far
  bool source_done = false;
  std::exception_ptr source_error;
  uint64_t received = 0, skipped = 0, failed = 0, reconnections = 0;
  const auto start = std::chrono::steady_clock::now();
  grpc::Status status;
  // With `mutex` held: nothing more to take from the source.
  auto exhausted = [&] { return source_done || (max_frames > 0 && taken >= max_frames); };

  for (int failures_in_a_row = 0;;) {
    // A reconnection gets a channel of its own: the old one may still be backing off from the
    // server it lost, and would fail the new call at once.
    auto stub = FurnitureRecognizer::NewStub(connection.channel(/*own_connection=*/reconnections > 0));
    grpc::ClientContext context;
    connection.prepare(&context);
    auto stream = stub->StreamFrames(&context);
    bool answered_any = false;

    std::thread writer([&] {
      ism::v1::StreamFramesRequest request;
      auto* settings = request.mutable_settings();
      settings->set_policy(latest_wins ? ism::v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS
                                       : ism::v1::BACKPRESSURE_POLICY_EVERY_FRAME);
      *settings->mutable_options() = flags.build();
      // Never called with `mutex` held: Write waits for flow control, which waits for the reader.
      auto send = [&](uint64_t id, const SentFrame& frame) {
        request.set_frame_id(id);
        request.set_timestamp_us(frame.timestamp_us);
        *request.mutable_scene() = frame.scene;
        const bool ok = stream->Write(request);
        request.clear_settings();  // the first message of each stream carries them
        return ok;
      };
      try {
        std::vector<std::pair<uint64_t, SentFrame>> again;
        {
          std::lock_guard<std::mutex> lock(mutex);
          again.assign(unanswered.begin(), unanswered.end());
        }
        bool open = true;
        for (const auto& [id, frame] : again) {
          if (!(open = send(id, frame))) break;  // the call is over; Finish says why
        }
        while (open) {
          {
            std::lock_guard<std::mutex> lock(mutex);
            if (exhausted()) break;
          }
          auto next = source->next();
          if (!next) {
            std::lock_guard<std::mutex> lock(mutex);
            source_done = true;
            break;
          }
          SentFrame frame{next->timestamp_us, std::move(next->scene)};
          uint64_t id;
          {
            std::lock_guard<std::mutex> lock(mutex);
            id = ++taken;
            unanswered[id] = frame;
          }
          open = send(id, frame);
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        source_error = std::current_exception();
        source_done = true;
      }
      stream->WritesDone();
    });

    ism::v1::FrameResult result;
    while (stream->Read(&result)) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        unanswered.erase(result.frame_id());
        for (auto id : result.skipped_frame_ids()) unanswered.erase(id);
      }
      answered_any = true;
      ++received;
      skipped += result.skipped_frame_ids_size();
      const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (connection.json) {
        std::cout << ism::client::toJson(result) << std::endl;  // a line per result as it comes, also into a pipe
        continue;
      }
      std::cout << "frame " << result.frame_id() << ": ";
      if (result.has_error()) {
        ++failed;
        std::cout << "error " << statusName(static_cast<grpc::StatusCode>(result.error().code())) << ": "
                  << result.error().message();
      } else {
        std::cout << result.result().hypotheses_size() << " hypotheses";
        for (const auto& h : result.result().hypotheses()) {
          std::cout << " [" << h.category() << " " << std::fixed << std::setprecision(2) << h.score() << " at ("
                    << h.center().x() << ", " << h.center().y() << ", " << h.center().z() << ")]";
        }
        std::cout << std::fixed << std::setprecision(1) << ", " << result.result().total_ms() << " ms";
      }
      if (result.skipped_frame_ids_size() > 0) {
        std::cout << ", skipped";
        for (auto id : result.skipped_frame_ids()) std::cout << " " << id;
      }
      std::cout << std::fixed << std::setprecision(1) << " (" << received / elapsed << " fps)" << std::endl;
    }
    writer.join();
    status = stream->Finish();

    std::unique_lock<std::mutex> lock(mutex);
    if (status.error_code() != grpc::StatusCode::UNAVAILABLE || source_error) break;
    if (exhausted() && unanswered.empty()) {
      status = grpc::Status::OK;  // broke after the last answer: nothing is missing
      break;
    }
    if (answered_any) failures_in_a_row = 0;
    if (++failures_in_a_row > reconnect_attempts) {
      status = grpc::Status(status.error_code(),
                            status.error_message() + " (gave up after " + std::to_string(reconnect_attempts) +
                                " reconnection attempts; " + std::to_string(unanswered.size()) +
                                " frames sent were not answered)");
      break;
    }
    auto delay = kFirstReconnectDelay * (1 << std::min(failures_in_a_row - 1, 10));
    if (delay > kMaxReconnectDelay) delay = std::chrono::duration_cast<std::chrono::milliseconds>(kMaxReconnectDelay);
    std::cerr << "stream broke: " << statusName(status.error_code()) << ": " << status.error_message() << "; "
              << unanswered.size() << " frames unanswered; reconnecting in " << std::fixed << std::setprecision(2)
              << std::chrono::duration<double>(delay).count() << " s (attempt " << failures_in_a_row << " of "
              << reconnect_attempts << ")\n";
    lock.unlock();
    std::this_thread::sleep_for(delay);
    ++reconnections;
  }

  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cerr << taken << " frames sent, " << received << " results (" << failed << " failed), " << skipped
            << " skipped, " << reconnections << " reconnections, " << std::fixed << std::setprecision(2)
            << received / elapsed << " results/s over " << elapsed << " s\n";
  if (!status.ok()) return fail("stream", status);
  if (source_error) {
    try {
      std::rethrow_exception(source_error);
    } catch (const std::exception& e) {
      std::cerr << "error: " << e.what() << "\n";
    }
    return kLocalFailure;
  }
  return 0;
}

int runModels(const Connection& connection, const std::string& show) {
  auto stub = FurnitureRecognizer::NewStub(connection.channel());
  grpc::ClientContext context;
  connection.prepare(&context);
  if (!show.empty()) {
    ism::v1::GetModelRequest request;
    request.set_name(show);
    ism::v1::ModelInfo model;
    const grpc::Status status = stub->GetModel(&context, request, &model);
    if (!status.ok()) return fail("models show " + show, status);
    if (connection.json) {
      std::cout << ism::client::toJson(model) << "\n";
    } else {
      ism::client::printModel(std::cout, model);
    }
    return 0;
  }
  ism::v1::ListModelsResponse models;
  const grpc::Status status = stub->ListModels(&context, {}, &models);
  if (!status.ok()) return fail("models", status);
  if (connection.json) {
    std::cout << ism::client::toJson(models) << "\n";
  } else {
    ism::client::printModelList(std::cout, models);
  }
  return 0;
}

int runHealth(const Connection& connection) {
  auto stub = grpc::health::v1::Health::NewStub(connection.channel());
  grpc::ClientContext context;
  connection.prepare(&context);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, {}, &response);
  if (!status.ok()) return fail("health", status);
  std::cout << grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status()) << "\n";
  return response.status() == grpc::health::v1::HealthCheckResponse::SERVING
             ? 0
             : kStatusBase + grpc::StatusCode::UNAVAILABLE;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ism-client: talk to an ism-server (furniture recognition with 3D Implicit Shape Models)"};
  app.footer(kExitCodes);
  app.require_subcommand(1);
  app.fallthrough();  // --server and friends may follow the subcommand too
  Connection connection;
  connection.add(&app);

  auto* recognize = app.add_subcommand("recognize", "recognise furniture in PCD/PLY clouds or 16-bit depth PNGs");
  std::vector<std::string> files;
  recognize->add_option("files", files, "scene files (.pcd, .ply, .png)")->required();
  RecognitionFlags recognize_flags;
  recognize_flags.add(recognize);
  std::string picture;
  recognize->add_option("--picture", picture,
                        "draw the hypotheses' boxes over the scene as seen by the sensor into this PNG "
                        "(several files: one PNG each, named after the file)");

  auto* stream = app.add_subcommand("stream", "stream depth frames and print one result per frame");
  std::string device, folder;
  std::string policy = "latest";
  uint64_t max_frames = 0;
  auto* device_option =
      stream->add_option("--device", device, "OpenNI2 device URI or .oni recording (no value: the first sensor)")
          ->expected(0, 1);
  auto* folder_option = stream->add_option("--folder", folder, "folder of 16-bit depth PNGs (TUM: its depth/ folder)");
  device_option->excludes(folder_option);
  stream->add_option("--policy", policy, "backpressure: 'every' frame or 'latest' frame wins")
      ->check(CLI::IsMember({"every", "latest"}))
      ->capture_default_str();
  stream->add_option("--max-frames", max_frames, "stop after this many frames (0: all)");
  int reconnect_attempts = 6;
  stream->add_option("--reconnect-attempts", reconnect_attempts,
                     "when the stream breaks with UNAVAILABLE (server restarted or gone), reconnect up to this many "
                     "times in a row, waiting 0.25 s, 0.5 s, ... up to 8 s between attempts, and resend the frames "
                     "not answered yet (0: give up at once)")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  RecognitionFlags stream_flags;
  stream_flags.add(stream);

  auto* models = app.add_subcommand("models", "list the server's models");
  auto* show = models->add_subcommand("show", "everything about one model");
  std::string show_name;
  show->add_option("name", show_name, "model name")->required();

  auto* health = app.add_subcommand("health", "ask the standard gRPC health service");

  auto* bench = app.add_subcommand("bench", "load-test the server (in the style of ghz) and report throughput, "
                                            "latency percentiles and errors by status");
  ism::client::BenchParams bench_params;
  bench_params.add(bench);
  RecognitionFlags bench_flags;
  bench_flags.add(bench);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kUsageError;
  }

  try {
    if (recognize->parsed()) return runRecognize(connection, files, recognize_flags, picture);
    if (stream->parsed()) {
      if (device_option->count() == 0 && folder.empty()) {
        std::cerr << "stream: give --device [URI|FILE.oni] or --folder DIR\n";
        return kUsageError;
      }
      auto source = folder.empty() ? ism::client::openOpenNi(device)
                                   : ism::client::openPngFolder(folder, stream_flags.intrinsics);
      return runStream(connection, std::move(source), stream_flags, policy == "latest", max_frames,
                       reconnect_attempts);
    }
    if (models->parsed()) return runModels(connection, show->parsed() ? show_name : "");
    if (health->parsed()) return runHealth(connection);
    if (bench->parsed()) {
      const auto report = ism::client::runBench(connection, bench_params, bench_flags);
      if (connection.json) {
        std::cout << ism::client::benchJson(report) << "\n";
      } else {
        ism::client::printBenchTable(std::cout, report);
      }
      return ism::client::benchExitCode(report);
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kLocalFailure;
  }
  return kUsageError;
}
