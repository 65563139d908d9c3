#pragma once
// What the ism-client subcommands share: exit codes, connection flags, recognition flags and
// scenes read from files, so that `recognize`, `stream` and `bench` send the same requests.
#include <grpcpp/grpcpp.h>

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/io/cloud_io.h"
#include "core/model/model.h"
#include "core/recognition/recognizer.h"
#include "core/report/report.h"
#include "ism/v1/service.pb.h"

namespace CLI {
class App;
}

namespace ism::client {

constexpr int kLocalFailure = 1;
constexpr int kUsageError = 2;
constexpr int kStatusBase = 10;  // + the gRPC status code

struct Connection {
  std::string server = "localhost:50051";
  int deadline_ms = 0;
  bool json = false;
  bool tls = false;
  std::string tls_ca, tls_cert, tls_key, tls_server_name;
  std::string token;

  void add(CLI::App* app);
  // `own_connection`: subchannels of its own rather than gRPC's shared pool, so that a channel
  // made to reconnect does not inherit another's backoff from a server that went away.
  std::shared_ptr<grpc::Channel> channel(bool own_connection = false) const;
  void prepare(grpc::ClientContext* context) const;
};

std::string statusName(grpc::StatusCode code);  // "UNAVAILABLE"

// What `recognize`, `stream` and `bench` send.
struct RecognitionFlags {
  v1::RecognitionOptions options;
  std::vector<std::string> categories;
  float min_score = NAN;
  CodebookType codebook = CodebookType::kGlobal;
  ActivationStrategy activation = ActivationStrategy::kKnn;
  VoteWeighting weighting = VoteWeighting::kLocalization;
  bool no_box_selection = false;
  RecognitionPreset preset = RecognitionPreset::kDefault;
  float min_confidence = NAN;  // NaN: the server's default
  bool keep_overlaps = false;
  bool no_verify = false;
  std::optional<Eigen::Vector3f> up;  // of every scene sent
  DepthIntrinsics intrinsics;  // of depth PNGs

  void add(CLI::App* app);
  v1::RecognitionOptions build() const;
  // What the flags say about a scene rather than the options: its up.
  void applyTo(v1::Scene* scene) const;
};

// A cloud as the wire carries it: an organized cloud as its whole image grid, NaN where no point
// was kept (the server finds keypoints on occluding contours only in an image), colour when there
// is some, the sensor pose.
v1::Scene cloudMessage(const Scene& scene);

// A file as the wire carries it, plus the decoded scene for --picture.
struct FileScene {
  v1::Scene message;
  Scene scene;
  PictureParams camera;  // the sensor the picture is drawn from
};

FileScene sceneFromFile(const std::string& path, const DepthIntrinsics& intrinsics, bool decode_png);

}  // namespace ism::client
