#include "client/cli/common.h"

#include <absl/status/status.h>

#include <CLI/CLI.hpp>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <sstream>

#include "core/common/cli_checks.h"
#include "core/io/cloud_io.h"
#include "core/io/depth_png.h"
#include "core/io/file_bytes.h"
#include "proto/wire/enums.h"
#include "proto/wire/messages.h"

namespace ism::client {

void Connection::add(CLI::App* app) {
  app->add_option("--server", server, "host:port of the server")->envname("ISM_SERVER")->capture_default_str();
  app->add_option("--deadline-ms", deadline_ms, "give up after this long (0: never)")->check(ism::cli::nonNegative());
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

std::shared_ptr<grpc::Channel> Connection::channel(bool own_connection) const {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 * 1024 * 1024);
  if (own_connection) args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  std::shared_ptr<grpc::ChannelCredentials> credentials = grpc::InsecureChannelCredentials();
  if (tls || !tls_ca.empty() || !tls_cert.empty() || !tls_server_name.empty()) {
    grpc::SslCredentialsOptions options;
    if (!tls_ca.empty()) options.pem_root_certs = readFileBytes(tls_ca);
    if (!tls_cert.empty()) {
      options.pem_cert_chain = readFileBytes(tls_cert);
      options.pem_private_key = readFileBytes(tls_key);
    }
    if (!tls_server_name.empty()) args.SetSslTargetNameOverride(tls_server_name);
    credentials = grpc::SslCredentials(options);
  }
  return grpc::CreateCustomChannel(server, credentials, args);
}

// Per-call metadata rather than call credentials: gRPC sends those only over TLS, and a
// token over plain text is legitimate behind a TLS-terminating proxy or on loopback.
void Connection::prepare(grpc::ClientContext* context) const {
  if (deadline_ms > 0) context->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(deadline_ms));
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

// grpc::StatusCode and absl::StatusCode share their numbering by design.
std::string statusName(grpc::StatusCode code) {
  return absl::StatusCodeToString(static_cast<absl::StatusCode>(code));
}

namespace {

// The names core gives the strategy's enums ("global", "knn", "lw"...), for the flags.
template <typename Enum>
CLI::Validator byName(std::initializer_list<Enum> values) {
  std::map<std::string, Enum> names;
  for (Enum value : values) names[toString(value)] = value;
  return CLI::CheckedTransformer(names).description("");
}

}  // namespace

void RecognitionFlags::add(CLI::App* app) {
  app->add_option_function<std::string>("--model", [this](const std::string& v) { options.set_model(v); },
                                        "model name (default: the only or 'default' one)");
  app->add_option("--category", categories, "categories to look for (repeatable; default: all)");
  app->add_option("--min-score", min_score, "score threshold instead of the model's");
  app->add_option_function<unsigned>("--max-hypotheses", [this](unsigned v) { options.set_max_hypotheses(v); },
                                     "at most this many hypotheses, best first");
  app->add_option("--codebook", codebook, "global or separated")
      ->type_name("NAME")
      ->transform(byName({CodebookType::kGlobal, CodebookType::kSeparated}))
      ->default_str(toString(codebook));
  app->add_option("--activation", activation, "knn or cutoff")
      ->type_name("NAME")
      ->transform(byName({ActivationStrategy::kKnn, ActivationStrategy::kCutoff}))
      ->default_str(toString(activation));
  app->add_option_function<int>("--k", [this](int v) { options.mutable_strategy()->set_k(v); },
                                "kNN activation: codewords per descriptor (default: the model's)")
      ->check(ism::cli::positive());
  app->add_option_function<float>("--cutoff", [this](float v) { options.mutable_strategy()->set_cutoff(v); },
                                  "cutoff activation: descriptor distance (default: the model's)")
      ->check(ism::cli::positive());
  app->add_option("--weighting", weighting, "vote weights: cw, lw or aw")
      ->type_name("NAME")
      ->transform(byName({VoteWeighting::kCategorization, VoteWeighting::kLocalization, VoteWeighting::kActivation}))
      ->default_str(toString(weighting));
  app->add_flag_function("--keypoints", [this](int64_t) { options.set_return_keypoints(true); },
                         "return each hypothesis' supporting keypoints");
  app->add_flag("--no-box-selection", no_box_selection, "seed preset: also return hypotheses whose box fails the test");
  app->add_option("--preset", preset,
                  "default (calibrated confidence, upright boxes, one answer per object) or seed (the seed's "
                  "pipeline: score over its threshold, learned box limits)")
      ->type_name("NAME")
      // Spelled out: core's names for presets live in its recognition library, which the client
      // does not link.
      ->transform(CLI::CheckedTransformer(
                      std::map<std::string, RecognitionPreset>{{"default", RecognitionPreset::kDefault},
                                                               {"seed", RecognitionPreset::kSeed}})
                      .description(""))
      ->default_str("default");
  app->add_option("--min-confidence", min_confidence, "default preset: drop hypotheses less confident (server "
                                                      "default 0.3)")
      ->check(CLI::Range(0.0f, 0.99f));
  app->add_flag("--keep-overlaps", keep_overlaps,
                "default preset: every confident peak, not one answer per object");
  app->add_flag("--no-verify", no_verify, "default preset: do not check hypotheses against the scene's depth");
  app->add_option_function<std::string>(
         "--up",
         [this](const std::string& text) {
           // The server would refuse such a vector too; refused here, it is a usage error.
           std::stringstream in(text);
           Eigen::Vector3f v;
           char comma1 = 0, comma2 = 0;
           if (!(in >> v.x() >> comma1 >> v.y() >> comma2 >> v.z()) || comma1 != ',' || comma2 != ',' ||
               !in.eof() || !v.allFinite() || !(v.norm() > 1e-6f)) {
             throw CLI::ValidationError("--up", "'" + text + "' is not three numbers X,Y,Z of a non-zero vector");
           }
           up = v;
         },
         "the scenes' up direction X,Y,Z in their coordinates, when known (default: the server finds the floor)")
      ->type_name("X,Y,Z");
  app->add_option("--fx", intrinsics.fx, "depth PNG focal length x (px)")->capture_default_str();
  app->add_option("--fy", intrinsics.fy, "depth PNG focal length y (px)")->capture_default_str();
  app->add_option("--cx", intrinsics.cx, "depth PNG principal point x (px)")->capture_default_str();
  app->add_option("--cy", intrinsics.cy, "depth PNG principal point y (px)")->capture_default_str();
  app->add_option("--depth-scale", intrinsics.depth_scale, "depth PNG units per metre (5000 for TUM RGB-D)")
      ->capture_default_str();
}

v1::RecognitionOptions RecognitionFlags::build() const {
  v1::RecognitionOptions out = options;
  for (const auto& c : categories) out.add_categories(c);
  if (!std::isnan(min_score)) out.set_min_score(min_score);
  if (no_box_selection) out.set_box_selection(false);
  auto* s = out.mutable_strategy();
  s->set_codebook(wire::toProto(codebook));
  s->set_activation(wire::toProto(activation));
  s->set_weighting(wire::toProto(weighting));
  out.set_preset(wire::toProto(preset));
  if (!std::isnan(min_confidence)) out.set_min_confidence(min_confidence);
  if (keep_overlaps) out.set_one_answer_per_object(false);
  if (no_verify) out.set_verify(false);
  return out;
}

void RecognitionFlags::applyTo(v1::Scene* scene) const {
  if (up) wire::toProto(*up, scene->mutable_up());
}

// PCD/PLY through core's loaders (NaNs dropped, sensor pose kept); PNG sent as it is and
// decoded here only for a picture.
v1::Scene cloudMessage(const Scene& scene) {
  v1::Scene message;
  auto* cloud = message.mutable_cloud();
  // An organized cloud goes out as its whole image grid, NaN where there is no point: the
  // server's front end finds keypoints on occluding contours only in an image.
  const bool organized = scene.image_width > 0 && scene.image_height > 0;
  const size_t slots = organized ? static_cast<size_t>(scene.image_width) * scene.image_height : scene.cloud->size();
  if (organized) {
    cloud->set_width(static_cast<uint32_t>(scene.image_width));
    cloud->set_height(static_cast<uint32_t>(scene.image_height));
  }
  // Written straight into the message's bytes (little-endian float32, as the wire wants), not
  // built in a vector and copied: a 640x480 frame is 3.7 MB of xyz.
  std::string* xyz = cloud->mutable_xyz();
  xyz->resize(slots * 3 * sizeof(float));
  char* xyz_out = xyz->data();
  if (organized) {
    const float nan[3] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN(),
                          std::numeric_limits<float>::quiet_NaN()};
    for (size_t slot = 0; slot < slots; ++slot) std::memcpy(xyz_out + slot * sizeof nan, nan, sizeof nan);
  }
  // No colour (Cloud.rgb): recognition reads geometry only, and a frame's colour is a fifth of
  // the request (0.9 of 4.4 MB), which every call would serialise, send and parse for nothing.
  // Pictures are drawn here, from the local scene.
  for (size_t i = 0; i < scene.cloud->size(); ++i) {
    const auto& p = (*scene.cloud)[i];
    const size_t slot = organized ? static_cast<size_t>(scene.pixel_index[i]) : i;
    const float point[3] = {p.x, p.y, p.z};
    std::memcpy(xyz_out + slot * sizeof point, point, sizeof point);
  }
  wire::toProto(scene.sensor_origin, message.mutable_sensor_origin());
  wire::toProto(scene.sensor_orientation, message.mutable_sensor_orientation());
  return message;
}

FileScene sceneFromFile(const std::string& path, const DepthIntrinsics& intrinsics, bool decode_png) {
  FileScene out;
  std::string extension = std::filesystem::path(path).extension().string();
  for (auto& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".png") {
    auto* depth = out.message.mutable_depth();
    depth->set_encoding(v1::DEPTH_ENCODING_PNG);
    depth->set_data(readFileBytes(path));
    // Checked here as the server would, so that a wrong flag fails before anything is sent.
    *depth->mutable_intrinsics() = wire::intrinsicsToProto(intrinsics);
    wire::intrinsicsFromProto(depth->intrinsics(), "intrinsics");
    if (decode_png) {
      out.scene = decodeDepthPng(depth->data(), intrinsics, path);
      static_cast<PinholeIntrinsics&>(out.camera) = intrinsics;
      out.camera.width = out.scene.image_width;
      out.camera.height = out.scene.image_height;
    }
    return out;
  }
  out.scene = loadCloudFile(path);
  out.message = cloudMessage(out.scene);
  return out;
}

}  // namespace ism::client
