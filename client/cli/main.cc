// ism-client: command-line client of the furniture recognition service.
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <filesystem>
#include <iostream>

#include "client/cli/bench.h"
#include "client/cli/common.h"
#include "client/cli/frame_source.h"
#include "client/cli/output.h"
#include "client/cli/stream.h"
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
      flags.applyTo(request.mutable_scene());
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
        const ism::RecognitionResult result = ism::wire::resultFromProto(response.result());
        ism::PictureParams camera = scene.camera;
        if (result.gravity) camera.up = result.gravity->up;
        ism::savePicture(scene.scene, result.hypotheses, path, camera);
      } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << "\n";
        if (exit_code == 0) exit_code = kLocalFailure;
      }
    }
  }
  return exit_code;
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
  auto* device_option =
      stream->add_option("--device", device, "OpenNI2 device URI or .oni recording (no value: the first sensor)")
          ->expected(0, 1);
  auto* folder_option = stream->add_option("--folder", folder, "folder of 16-bit depth PNGs (TUM: its depth/ folder)");
  device_option->excludes(folder_option);
  stream->add_option("--policy", policy, "backpressure: 'every' frame or 'latest' frame wins")
      ->check(CLI::IsMember({"every", "latest"}))
      ->capture_default_str();
  ism::client::StreamParams stream_params;
  stream->add_option("--max-frames", stream_params.max_frames, "stop after this many frames (0: all)");
  stream->add_option("--reconnect-attempts", stream_params.reconnect_attempts,
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
      stream_params.latest_wins = policy == "latest";
      return ism::client::runStream(connection, *source, stream_flags, stream_params);
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
