#include "server/conversion.h"

#include <grpcpp/support/proto_buffer_reader.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <grpcpp/support/proto_buffer_writer.h>
#include <pcl/common/transforms.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "core/common/error.h"
#include "core/io/scene_bytes.h"
#include "proto/wire/enums.h"
#include "proto/wire/messages.h"

namespace ism::server {
namespace {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "wire formats are little-endian");

Error invalid(const std::string& message) { return Error(ErrorCode::kInvalidInput, message); }

void checkSize(size_t count, size_t limit, const char* what) {
  if (count > limit) {
    throw Error(ErrorCode::kResourceExhausted, std::string(what) + " has " + std::to_string(count) +
                                                   ", more than the server's limit of " + std::to_string(limit));
  }
}

Scene cloudScene(const v1::PointCloud& cloud, const InputLimits& limits, SceneBuffers* buffers) {
  if (cloud.xyz().empty()) throw invalid("scene.cloud.xyz is empty: the cloud has no points");
  if (cloud.xyz().size() % 12 != 0) {
    throw invalid("scene.cloud.xyz has " + std::to_string(cloud.xyz().size()) +
                  " bytes, not a multiple of 12 (float32 x, y, z per point)");
  }
  const size_t count = cloud.xyz().size() / 12;
  checkSize(count, limits.max_points, "scene.cloud points");
  if (!cloud.rgb().empty() && cloud.rgb().size() != 3 * count) {
    throw invalid("scene.cloud.rgb has " + std::to_string(cloud.rgb().size()) + " bytes but xyz has " +
                  std::to_string(count) + " points (expected " + std::to_string(3 * count) + " bytes)");
  }
  uint64_t width = cloud.width(), height = cloud.height();
  if (width == 0 && height == 0) {
    width = count;
    height = 1;
  } else if (width * height != count) {
    throw invalid("scene.cloud is declared " + std::to_string(width) + "x" + std::to_string(height) + " = " +
                  std::to_string(width * height) + " points but xyz has " + std::to_string(count));
  }
  // Straight from the request's bytes (sceneFromPacked reads them unaligned), into the worker's
  // kept cloud when it has one.
  Scene reuse;
  if (buffers != nullptr) {
    reuse.cloud = std::move(buffers->cloud);
    reuse.pixel_index = std::move(buffers->pixel_index);
  }
  return sceneFromPacked(cloud.xyz().data(), count,
                         cloud.rgb().empty() ? nullptr : reinterpret_cast<const uint8_t*>(cloud.rgb().data()),
                         static_cast<int>(width), static_cast<int>(height), "request", &reuse);
}

// Width and height from the PNG header, so an oversized image is refused before it is inflated.
std::pair<uint32_t, uint32_t> pngSize(const std::string& png) {
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (png.size() < 24 || png.compare(0, 8, kSignature, 8) != 0 || png.compare(12, 4, "IHDR") != 0) {
    throw invalid("scene.depth.data (" + std::to_string(png.size()) + " bytes) is not a PNG image");
  }
  auto be32 = [&](size_t at) {
    const auto* b = reinterpret_cast<const unsigned char*>(png.data()) + at;
    return uint32_t(b[0]) << 24 | uint32_t(b[1]) << 16 | uint32_t(b[2]) << 8 | uint32_t(b[3]);
  };
  return {be32(16), be32(20)};
}

Scene depthScene(const v1::DepthImage& depth, const InputLimits& limits, const ShouldStop& should_stop) {
  const DepthIntrinsics intrinsics = wire::intrinsicsFromProto(depth.intrinsics(), "scene.depth.intrinsics");
  const uint64_t width = depth.width(), height = depth.height();
  switch (depth.encoding()) {
    case v1::DEPTH_ENCODING_RAW_UINT16_LE: {
      if (width == 0 || height == 0) {
        throw invalid("scene.depth.width and height are required for RAW_UINT16_LE (got " + std::to_string(width) +
                      "x" + std::to_string(height) + ")");
      }
      checkSize(width * height, limits.max_pixels, "scene.depth pixels");
      if (depth.data().size() != 2 * width * height) {
        throw invalid("scene.depth.data has " + std::to_string(depth.data().size()) + " bytes but a " +
                      std::to_string(width) + "x" + std::to_string(height) + " uint16 image needs " +
                      std::to_string(2 * width * height));
      }
      // Protobuf gives no alignment guarantee for bytes fields, so copy before reading as uint16.
      std::vector<uint16_t> pixels(width * height);
      std::memcpy(pixels.data(), depth.data().data(), depth.data().size());
      return depthToScene(pixels.data(), static_cast<int>(width), static_cast<int>(height), intrinsics, "request");
    }
    case v1::DEPTH_ENCODING_PNG: {
      const auto [png_width, png_height] = pngSize(depth.data());
      checkSize(uint64_t(png_width) * png_height, limits.max_pixels, "scene.depth PNG pixels");
      if ((width != 0 || height != 0) && (width != png_width || height != png_height)) {
        throw invalid("scene.depth is declared " + std::to_string(width) + "x" + std::to_string(height) +
                      " but the PNG is " + std::to_string(png_width) + "x" + std::to_string(png_height));
      }
      return decodeDepthPng(depth.data(), intrinsics, "request PNG", should_stop);
    }
    case v1::DEPTH_ENCODING_UNSPECIFIED:
      throw invalid("scene.depth.encoding is unset: use DEPTH_ENCODING_RAW_UINT16_LE or DEPTH_ENCODING_PNG");
    default:
      throw invalid("scene.depth.encoding " + std::to_string(depth.encoding()) + " is not supported");
  }
}

// The codewords a kNN activation can choose from: the global codebook's, or the largest
// category's own (0 when the model has no such codebook; recognition then says so).
int largestCodebook(const Model& model, CodebookType type) {
  if (type == CodebookType::kGlobal) return model.global_codebook ? model.global_codebook->size() : 0;
  int largest = 0;
  for (const auto& category : model.categories) {
    if (category.own_codebook) largest = std::max(largest, category.own_codebook->size());
  }
  return largest;
}

}  // namespace

void decodeMessage(const grpc::ByteBuffer& bytes, const std::string& what, google::protobuf::MessageLite* out) {
  // A message of 0 bytes is valid (every field at its default), but gRPC hands it over as a
  // buffer without slices, which its reader refuses.
  if (bytes.Length() == 0) {
    out->Clear();
    return;
  }
  grpc::ByteBuffer shared(bytes);  // shares the slices: the reader wants a mutable buffer
  grpc::ProtoBufferReader reader(&shared);
  if (!reader.status().ok() || !out->ParseFromZeroCopyStream(&reader)) {
    throw invalid(what + " (" + std::to_string(bytes.Length()) + " bytes) is not a valid " + out->GetTypeName() +
                  ": protobuf cannot decode it (malformed or truncated, or a string that is not UTF-8)");
  }
}

void encodeMessage(const google::protobuf::MessageLite& message, grpc::ByteBuffer* out) {
  bool own_buffer = false;
  const grpc::Status status = grpc::GenericSerialize<grpc::ProtoBufferWriter, google::protobuf::MessageLite>(
      message, out, &own_buffer);
  if (!status.ok()) {
    throw Error(ErrorCode::kInternal, "cannot encode " + message.GetTypeName() + ": " + status.error_message());
  }
}

void SceneBuffers::recycle(Scene& scene) {
  if (scene.cloud && scene.cloud.use_count() == 1 && scene.cloud->points.capacity() <= kMaxKeptPoints) {
    cloud = std::move(scene.cloud);
    cloud->clear();
  }
  if (scene.pixel_index.capacity() <= kMaxKeptPoints) {
    pixel_index = std::move(scene.pixel_index);
    pixel_index.clear();
  }
}

Scene sceneFromProto(const v1::Scene& scene, const InputLimits& limits, SceneBuffers* buffers,
                     const ShouldStop& should_stop) {
  const Eigen::Vector3f origin = wire::fromProto(scene.sensor_origin());
  Eigen::Quaternionf orientation = wire::fromProto(scene.sensor_orientation());
  if (!origin.allFinite() || !orientation.coeffs().allFinite()) {
    throw invalid("scene.sensor_origin / sensor_orientation contain NaN or Inf");
  }
  if (orientation.coeffs().isZero()) {
    orientation = Eigen::Quaternionf::Identity();
  } else {
    orientation.normalize();
  }
  const std::optional<Eigen::Vector3f> up = wire::upFromProto(scene);  // checked before the costly decoding

  Scene out;
  switch (scene.data_case()) {
    case v1::Scene::kCloud:
      out = cloudScene(scene.cloud(), limits, buffers);
      break;
    case v1::Scene::kDepth: {
      out = depthScene(scene.depth(), limits, should_stop);
      // The image's points are in the camera frame: move them where the caller wants answers.
      Eigen::Affine3f pose = Eigen::Translation3f(origin) * orientation;
      if (!pose.matrix().isIdentity()) pcl::transformPointCloud(*out.cloud, *out.cloud, pose);
      break;
    }
    case v1::Scene::DATA_NOT_SET:
      throw invalid("scene has neither a cloud nor a depth image");
  }
  out.sensor_origin = origin;
  out.sensor_orientation = orientation;
  out.up = up;
  out.source = "request";
  return out;
}

size_t dropPointsBeyondRange(Scene* scene, float max_range_m) {
  auto& points = scene->cloud->points;
  const bool organized = !scene->pixel_index.empty();
  const double limit = static_cast<double>(max_range_m) * max_range_m;
  const Eigen::Vector3d origin = scene->sensor_origin.cast<double>();
  double nearest = std::numeric_limits<double>::infinity();
  size_t kept = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    // In double: the square of 1e30 is not a float.
    const double distance = (points[i].getVector3fMap().cast<double>() - origin).squaredNorm();
    if (distance > limit) {
      nearest = std::min(nearest, distance);
      continue;
    }
    points[kept] = points[i];
    if (organized) scene->pixel_index[kept] = scene->pixel_index[i];
    ++kept;
  }
  const size_t dropped = points.size() - kept;
  if (kept == 0) {
    throw invalid(fmt::format("scene: all {} points are farther than {:g} m from scene.sensor_origin (the nearest "
                              "at {:g} m): coordinates must be in metres, the sensor origin where the sensor was "
                              "(or raise ism-server's --max-range-m)",
                              dropped, max_range_m, std::sqrt(nearest)));
  }
  points.resize(kept);
  if (organized) scene->pixel_index.resize(kept);
  scene->cloud->width = static_cast<uint32_t>(kept);
  scene->cloud->height = 1;
  return dropped;
}

RecognitionOptions optionsFromProto(const v1::RecognitionOptions& in, const Model& model) {
  RecognitionOptions out;
  out.categories.assign(in.categories().begin(), in.categories().end());
  if (in.has_min_score()) {
    if (!std::isfinite(in.min_score())) throw invalid("options.min_score is not finite");
    out.min_score = in.min_score();
  }
  wire::answerOptionsFromProto(in, &out);
  out.max_hypotheses = static_cast<int>(in.max_hypotheses());
  out.box_selection = in.has_box_selection() ? in.box_selection() : true;
  out.return_keypoints = in.return_keypoints();

  // Unspecified enums take the defaults service.proto documents.
  const auto& s = in.strategy();
  const auto codebook = s.codebook() == v1::CODEBOOK_TYPE_UNSPECIFIED ? CodebookType::kGlobal
                                                                      : wire::codebookTypeFromProto(s.codebook());
  if (!codebook) throw invalid("options.strategy.codebook " + std::to_string(s.codebook()) + " is not supported");
  out.strategy.codebook = *codebook;
  const auto activation = s.activation() == v1::ACTIVATION_STRATEGY_UNSPECIFIED
                              ? ActivationStrategy::kKnn
                              : wire::activationStrategyFromProto(s.activation());
  if (!activation) {
    throw invalid("options.strategy.activation " + std::to_string(s.activation()) + " is not supported");
  }
  // Beyond these bounds k and the cutoff activate nothing more, only cost more.
  if (*activation == ActivationStrategy::kKnn) {
    if (s.k() < 0) throw invalid("options.strategy.k must be >= 0, got " + std::to_string(s.k()));
    const int codewords = largestCodebook(model, *codebook);
    if (codewords > 0 && s.k() > codewords) {
      throw invalid("options.strategy.k = " + std::to_string(s.k()) + " is more than the " +
                    std::to_string(codewords) + " codewords of the model's " + toString(*codebook) + " codebook");
    }
    out.strategy.activation = model.trained_knn;
    if (s.k() > 0) out.strategy.activation.k = s.k();
  } else {
    if (!(s.cutoff() >= 0 && std::isfinite(s.cutoff()))) {
      throw invalid("options.strategy.cutoff must be >= 0, got " + std::to_string(s.cutoff()));
    }
    if (s.cutoff() > kMaxDescriptorDistance) {
      throw invalid(fmt::format("options.strategy.cutoff = {:g} is more than {:g}, the largest distance between a "
                                "descriptor and a codeword",
                                s.cutoff(), kMaxDescriptorDistance));
    }
    out.strategy.activation = model.trained_cutoff;
    if (s.cutoff() > 0) out.strategy.activation.cutoff = s.cutoff();
  }
  const auto weighting = s.weighting() == v1::VOTE_WEIGHTING_UNSPECIFIED ? VoteWeighting::kLocalization
                                                                         : wire::voteWeightingFromProto(s.weighting());
  if (!weighting) throw invalid("options.strategy.weighting " + std::to_string(s.weighting()) + " is not supported");
  out.strategy.weighting = *weighting;
  return out;
}

void resultToProto(const RecognitionResult& result, const LoadedModel& model, v1::RecognitionResult* out) {
  wire::resultToProto(result, out);
  out->set_model_name(model.name);
  out->set_model_version(model.info.version());
}

}  // namespace ism::server
