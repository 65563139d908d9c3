// ism-client: command-line client of the furniture recognition service.
#include <absl/status/status.h>
#include <grpcpp/grpcpp.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>
#include <mutex>
#include <thread>

#include "client/cli/frame_source.h"
#include "client/cli/output.h"
#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/report/report.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "ism/v1/service.grpc.pb.h"

namespace {

using ism::v1::FurnitureRecognizer;

constexpr int kLocalFailure = 1;
constexpr int kUsageError = 2;
constexpr int kStatusBase = 10;

const char* kExitCodes = R"(Exit codes:
  0   success
  1   local failure: unreadable input file, no sensor attached
  2   usage error
  10+ the server's gRPC status code: 11 CANCELLED, 13 INVALID_ARGUMENT,
      14 DEADLINE_EXCEEDED, 15 NOT_FOUND, 18 RESOURCE_EXHAUSTED, 19 FAILED_PRECONDITION,
      23 INTERNAL, 24 UNAVAILABLE (server unreachable or not serving)
Environment: ISM_SERVER sets --server.)";

struct Connection {
  std::string server = "localhost:50051";
  int deadline_ms = 0;
  bool json = false;
  bool tls = false;
  std::string tls_ca, tls_cert, tls_key, tls_server_name;
  std::string token;

  void add(CLI::App* app) {
    app->add_option("--server", server, "host:port of the server")->envname("ISM_SERVER")->capture_default_str();
    app->add_option("--deadline-ms", deadline_ms, "give up after this long (0: never)")->check(CLI::NonNegativeNumber);
    app->add_flag("--json", json, "print JSON (one object per line) instead of tables");
    app->add_flag("--tls", tls, "connect with TLS, trusting the system's CAs (implied by the --tls-* options)");
    app->add_option("--tls-ca", tls_ca, "PEM CA certificates to trust instead of the system's")
        ->envname("ISM_TLS_CA")
        ->check(CLI::ExistingFile);
    auto* cert = app->add_option("--tls-cert", tls_cert, "PEM client certificate, for servers that require one (mTLS)")
                     ->check(CLI::ExistingFile);
    auto* key = app->add_option("--tls-key", tls_key, "PEM private key of --tls-cert")->check(CLI::ExistingFile);
    cert->needs(key);
    key->needs(cert);
    app->add_option("--tls-server-name", tls_server_name,
                    "name to check the server certificate against (default: the host of --server)");
    app->add_option("--token", token, "bearer token sent as 'authorization: Bearer TOKEN' (prefer ISM_TOKEN: "
                                      "arguments show in ps)")
        ->envname("ISM_TOKEN");
  }

  std::shared_ptr<grpc::Channel> channel() const {
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(64 * 1024 * 1024);
    std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
    if (tls || !tls_ca.empty() || !tls_cert.empty() || !tls_server_name.empty()) {
      grpc::SslCredentialsOptions options;
      if (!tls_ca.empty()) options.pem_root_certs = ism::readFileBytes(tls_ca);
      if (!tls_cert.empty()) {
        options.pem_cert_chain = ism::readFileBytes(tls_cert);
        options.pem_private_key = ism::readFileBytes(tls_key);
      }
      if (!tls_server_name.empty()) args.SetSslTargetNameOverride(tls_server_name);
      credentials = grpc::SslCredentials(options);
    }
    return grpc::CreateCustomChannel(server, credentials, args);
  }
  // Per-call metadata rather than call credentials: gRPC sends those only over TLS, and a
  // token over plain text is legitimate behind a TLS-terminating proxy or on loopback.
  void prepare(grpc::ClientContext* context) const {
    if (deadline_ms > 0) context->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(deadline_ms));
    if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
  }
};

// grpc::StatusCode and absl::StatusCode share their numbering by design.
std::string statusName(grpc::StatusCode code) {
  return absl::StatusCodeToString(static_cast<absl::StatusCode>(code));
}

int fail(const std::string& what, const grpc::Status& status) {
  std::cerr << "error: " << what << ": " << statusName(status.error_code()) << ": "
            << status.error_message() << "\n";
  return kStatusBase + status.error_code();
}

// What both `recognize` and `stream` send.
struct RecognitionFlags {
  ism::v1::RecognitionOptions options;
  std::vector<std::string> categories;
  float min_score = NAN;
  std::string codebook = "global", activation = "knn", weighting = "lw";
  bool no_box_selection = false;
  ism::v1::CameraIntrinsics intrinsics;

  void add(CLI::App* app) {
    intrinsics.set_fx(525.0f);
    intrinsics.set_fy(525.0f);
    intrinsics.set_cx(319.5f);
    intrinsics.set_cy(239.5f);
    intrinsics.set_depth_scale(1000.0f);
    app->add_option_function<std::string>("--model", [this](const std::string& v) { options.set_model(v); },
                                          "model name (default: the only or 'default' one)");
    app->add_option("--category", categories, "categories to look for (repeatable; default: all)");
    app->add_option("--min-score", min_score, "score threshold instead of the model's");
    app->add_option_function<unsigned>("--max-hypotheses", [this](unsigned v) { options.set_max_hypotheses(v); },
                                       "at most this many hypotheses, best first");
    app->add_option("--codebook", codebook, "global or separated")
        ->check(CLI::IsMember({"global", "separated"}))
        ->capture_default_str();
    app->add_option("--activation", activation, "knn or cutoff")
        ->check(CLI::IsMember({"knn", "cutoff"}))
        ->capture_default_str();
    app->add_option_function<int>("--k", [this](int v) { options.mutable_strategy()->set_k(v); },
                                  "kNN activation: codewords per descriptor (default: the model's)")
        ->check(CLI::PositiveNumber);
    app->add_option_function<float>("--cutoff", [this](float v) { options.mutable_strategy()->set_cutoff(v); },
                                    "cutoff activation: descriptor distance (default: the model's)")
        ->check(CLI::PositiveNumber);
    app->add_option("--weighting", weighting, "vote weights: cw, lw or aw")
        ->check(CLI::IsMember({"cw", "lw", "aw"}))
        ->capture_default_str();
    app->add_flag_function("--keypoints", [this](int64_t) { options.set_return_keypoints(true); },
                           "return each hypothesis' supporting keypoints");
    app->add_flag("--no-box-selection", no_box_selection, "also return hypotheses whose box fails the test");
    auto intrinsic = [&](const char* name, void (ism::v1::CameraIntrinsics::*set)(float), const char* help) {
      app->add_option_function<float>(name, [this, set](float v) { (intrinsics.*set)(v); }, help);
    };
    intrinsic("--fx", &ism::v1::CameraIntrinsics::set_fx, "depth PNG focal length x (px, default 525)");
    intrinsic("--fy", &ism::v1::CameraIntrinsics::set_fy, "depth PNG focal length y (px, default 525)");
    intrinsic("--cx", &ism::v1::CameraIntrinsics::set_cx, "depth PNG principal point x (px, default 319.5)");
    intrinsic("--cy", &ism::v1::CameraIntrinsics::set_cy, "depth PNG principal point y (px, default 239.5)");
    intrinsic("--depth-scale", &ism::v1::CameraIntrinsics::set_depth_scale,
              "depth PNG units per metre (default 1000; 5000 for TUM RGB-D)");
  }

  ism::v1::RecognitionOptions build() const {
    ism::v1::RecognitionOptions out = options;
    for (const auto& c : categories) out.add_categories(c);
    if (!std::isnan(min_score)) out.set_min_score(min_score);
    if (no_box_selection) out.set_box_selection(false);
    auto* s = out.mutable_strategy();
    s->set_codebook(codebook == "separated" ? ism::v1::CODEBOOK_TYPE_SEPARATED : ism::v1::CODEBOOK_TYPE_GLOBAL);
    s->set_activation(activation == "cutoff" ? ism::v1::ACTIVATION_STRATEGY_CUTOFF : ism::v1::ACTIVATION_STRATEGY_KNN);
    s->set_weighting(weighting == "cw"   ? ism::v1::VOTE_WEIGHTING_CATEGORIZATION
                     : weighting == "aw" ? ism::v1::VOTE_WEIGHTING_ACTIVATION
                                         : ism::v1::VOTE_WEIGHTING_LOCALIZATION);
    return out;
  }
};

// A file as the wire carries it, plus the decoded scene for --picture.
struct FileScene {
  ism::v1::Scene message;
  ism::Scene scene;
  ism::PictureParams camera;  // the sensor the picture is drawn from
};

// PCD/PLY through core's loaders (NaNs dropped, sensor pose kept); PNG sent as it is and
// decoded here only for a picture.
FileScene sceneFromFile(const std::string& path, const ism::v1::CameraIntrinsics& intrinsics, bool decode_png) {
  FileScene out;
  std::string extension = std::filesystem::path(path).extension().string();
  for (auto& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".png") {
    auto* depth = out.message.mutable_depth();
    depth->set_encoding(ism::v1::DEPTH_ENCODING_PNG);
    depth->set_data(ism::readFileBytes(path));
    *depth->mutable_intrinsics() = intrinsics;
    if (decode_png) {
      out.scene = ism::decodeDepthPng(depth->data(), {intrinsics.fx(), intrinsics.fy(), intrinsics.cx(),
                                                      intrinsics.cy(), intrinsics.depth_scale()}, path);
      out.camera.width = out.scene.image_width;
      out.camera.height = out.scene.image_height;
      out.camera.fx = intrinsics.fx();
      out.camera.fy = intrinsics.fy();
      out.camera.cx = intrinsics.cx();
      out.camera.cy = intrinsics.cy();
    }
    return out;
  }
  out.scene = ism::loadCloudFile(path);
  const ism::Scene& scene = out.scene;
  auto* cloud = out.message.mutable_cloud();
  // An organized cloud goes out as its whole image grid, NaN where there is no point: the
  // server's front end finds keypoints on occluding contours only in an image.
  const bool organized = scene.image_width > 0 && scene.image_height > 0;
  const size_t slots = organized ? static_cast<size_t>(scene.image_width) * scene.image_height : scene.cloud->size();
  if (organized) {
    cloud->set_width(static_cast<uint32_t>(scene.image_width));
    cloud->set_height(static_cast<uint32_t>(scene.image_height));
  }
  std::vector<float> xyz(slots * 3, std::numeric_limits<float>::quiet_NaN());
  std::string* rgb = cloud->mutable_rgb();
  if (scene.has_color) rgb->assign(slots * 3, '\0');
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    const auto& p = (*scene.cloud)[i];
    const size_t slot = organized ? static_cast<size_t>(scene.pixel_index[i]) : i;
    xyz[slot * 3] = p.x;
    xyz[slot * 3 + 1] = p.y;
    xyz[slot * 3 + 2] = p.z;
    if (scene.has_color) {
      (*rgb)[slot * 3] = static_cast<char>(p.r);
      (*rgb)[slot * 3 + 1] = static_cast<char>(p.g);
      (*rgb)[slot * 3 + 2] = static_cast<char>(p.b);
    }
  }
  cloud->set_xyz(reinterpret_cast<const char*>(xyz.data()), xyz.size() * sizeof(float));
  auto* origin = out.message.mutable_sensor_origin();
  origin->set_x(scene.sensor_origin.x());
  origin->set_y(scene.sensor_origin.y());
  origin->set_z(scene.sensor_origin.z());
  auto* q = out.message.mutable_sensor_orientation();
  q->set_w(scene.sensor_orientation.w());
  q->set_x(scene.sensor_orientation.x());
  q->set_y(scene.sensor_orientation.y());
  q->set_z(scene.sensor_orientation.z());
  return out;
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
        ism::savePicture(scene.scene, ism::client::fromProto(response.result()).hypotheses, path, scene.camera);
      } catch (const std::exception& e) {
        std::cerr << "error: " << e.what() << "\n";
        if (exit_code == 0) exit_code = kLocalFailure;
      }
    }
  }
  return exit_code;
}

int runStream(const Connection& connection, std::unique_ptr<ism::client::FrameSource> source,
              const RecognitionFlags& flags, bool latest_wins, uint64_t max_frames) {
  std::cerr << "streaming " << source->describe() << " (" << (latest_wins ? "latest frame wins" : "every frame")
            << ")\n";
  auto stub = FurnitureRecognizer::NewStub(connection.channel());
  grpc::ClientContext context;
  connection.prepare(&context);
  auto stream = stub->StreamFrames(&context);
  std::exception_ptr source_error;
  std::atomic<uint64_t> sent{0};
  const auto start = std::chrono::steady_clock::now();

  std::thread writer([&] {
    try {
      ism::v1::StreamFramesRequest request;
      auto* settings = request.mutable_settings();
      settings->set_policy(latest_wins ? ism::v1::BACKPRESSURE_POLICY_LATEST_FRAME_WINS
                                       : ism::v1::BACKPRESSURE_POLICY_EVERY_FRAME);
      *settings->mutable_options() = flags.build();
      while (max_frames == 0 || sent < max_frames) {
        auto frame = source->next();
        if (!frame) break;
        request.set_frame_id(sent + 1);
        request.set_timestamp_us(frame->timestamp_us);
        *request.mutable_scene() = std::move(frame->scene);
        if (!stream->Write(request)) break;  // the call is over; Finish says why
        ++sent;
        request.clear_settings();
      }
    } catch (...) {
      source_error = std::current_exception();
    }
    stream->WritesDone();
  });

  ism::v1::FrameResult result;
  uint64_t received = 0, skipped = 0, failed = 0;
  while (stream->Read(&result)) {
    ++received;
    skipped += result.skipped_frame_ids_size();
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (connection.json) {
      std::cout << ism::client::toJson(result) << "\n";
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
    std::cout << std::fixed << std::setprecision(1) << " (" << received / elapsed << " fps)\n";
  }
  writer.join();
  const grpc::Status status = stream->Finish();
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cerr << sent << " frames sent, " << received << " results (" << failed << " failed), " << skipped
            << " skipped, " << std::fixed << std::setprecision(2) << received / elapsed << " results/s over "
            << elapsed << " s\n";
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
  RecognitionFlags stream_flags;
  stream_flags.add(stream);

  auto* models = app.add_subcommand("models", "list the server's models");
  auto* show = models->add_subcommand("show", "everything about one model");
  std::string show_name;
  show->add_option("name", show_name, "model name")->required();

  auto* health = app.add_subcommand("health", "ask the standard gRPC health service");

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
      return runStream(connection, std::move(source), stream_flags, policy == "latest", max_frames);
    }
    if (models->parsed()) return runModels(connection, show->parsed() ? show_name : "");
    if (health->parsed()) return runHealth(connection);
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kLocalFailure;
  }
  return kUsageError;
}
