#include "core/model/model_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "core/common/error.h"
#include "ism/v1/model.pb.h"
#include "proto/wire/enums.h"

namespace ism {
namespace {

constexpr const char* kMagic = "ISM-MODEL";

uint32_t crc32Of(const std::string& bytes) {
  return static_cast<uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()),
                                       static_cast<uInt>(bytes.size())));
}

// --- Model -> proto ---

void toProto(const Codebook& codebook, v1::Codebook* out) {
  out->set_size(static_cast<uint32_t>(codebook.size()));
  out->set_dim(static_cast<uint32_t>(codebook.dim()));
  const auto& c = codebook.centers();
  out->mutable_centers()->Add(c.data(), c.data() + c.size());
}

void toProto(const VoteTable& table, v1::VoteTable* out) {
  out->mutable_offsets()->Add(table.offsets.begin(), table.offsets.end());
  auto* v = out->mutable_vectors();
  v->Reserve(static_cast<int>(table.vectors.size() * 3));
  for (const auto& vec : table.vectors) {
    v->Add(vec.x());
    v->Add(vec.y());
    v->Add(vec.z());
  }
  out->mutable_heights()->Add(table.heights.begin(), table.heights.end());
  out->mutable_objects()->Add(table.objects.begin(), table.objects.end());
  out->mutable_headings()->Add(table.headings.begin(), table.headings.end());
  out->mutable_codeword_weights()->Add(table.codeword_weights.begin(), table.codeword_weights.end());
}

void toProto(const GravityParams& g, v1::GravityParams* out) {
  out->set_enabled(g.enabled);
  out->set_max_tilt_deg(g.max_tilt_deg);
  out->set_given_up_tolerance_deg(g.given_up_tolerance_deg);
  out->set_inlier_distance(g.inlier_distance);
  out->set_noise_sigmas(g.noise_sigmas);
  out->set_min_floor_fraction(g.min_floor_fraction);
  out->set_max_below_fraction(g.max_below_fraction);
  out->set_below_margin(g.below_margin);
  out->set_wall_min_height(g.wall_min_height);
  out->set_wall_min_width(g.wall_min_width);
  out->set_wall_tilt_deg(g.wall_tilt_deg);
  out->set_max_walls(g.max_walls);
  out->set_iterations(g.iterations);
  out->set_sample_points(static_cast<uint32_t>(g.sample_points));
  out->set_seed(g.seed);
  out->set_wall_cell(g.wall_cell);
  out->set_wall_max_seen_through(g.wall_max_seen_through);
  out->set_given_up_kept_deg(g.given_up_kept_deg);
}

void toProto(const ActivationParams& a, v1::ActivationParams* out) {
  out->set_strategy(wire::toProto(a.strategy));
  out->set_k(a.k);
  out->set_cutoff(a.cutoff);
}

void writeCalibration(const Calibration& in, v1::Calibration* out) {
  out->set_a(in.a);
  out->set_b(in.b);
  out->set_c(in.c);
  out->set_d(in.d);
  out->set_e(in.e);
  out->set_min_score(in.min_score);
  out->set_positives(in.positives);
  out->set_negatives(in.negatives);
}

// --- proto -> Model, every size checked against the others ---

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw Error(ErrorCode::kCorruptModel, source_ + ": " + what);
  }

  Calibration calibration(const v1::Calibration& k, const std::string& where) const {
    if (!(std::isfinite(k.a()) && std::isfinite(k.b()) && std::isfinite(k.c()) && std::isfinite(k.d()) && std::isfinite(k.e()) &&
          k.min_score() >= 0 && std::isfinite(k.min_score()))) {
      fail(where + " has a calibration that is not finite");
    }
    Calibration calibration;
    calibration.a = k.a();
    calibration.b = k.b();
    calibration.c = k.c();
    calibration.d = k.d();
    calibration.e = k.e();
    calibration.min_score = k.min_score();
    calibration.positives = k.positives();
    calibration.negatives = k.negatives();
    return calibration;
  }

  Codebook codebook(const v1::Codebook& in, const std::string& where) const {
    // A zero dimension would pass the product check below with any size, and the codebook would
    // then allocate per-centre state for up to 2^32 centres (found by tests/fuzz).
    if (in.dim() == 0 || in.size() == 0) {
      fail(where + " has size " + std::to_string(in.size()) + " and dim " + std::to_string(in.dim()) +
           "; both must be positive");
    }
    if (static_cast<uint64_t>(in.centers_size()) != static_cast<uint64_t>(in.size()) * in.dim()) {
      fail(where + " has " + std::to_string(in.centers_size()) + " centre values, expected size " +
           std::to_string(in.size()) + " x dim " + std::to_string(in.dim()));
    }
    DescriptorMatrix centers(in.size(), in.dim());
    std::copy(in.centers().begin(), in.centers().end(), centers.data());
    return Codebook(std::move(centers));
  }

  VoteTable votes(const v1::VoteTable& in, int codebook_size, size_t objects, const std::string& where) const {
    VoteTable table;
    if (in.offsets_size() == 0 && in.vectors_size() == 0) return table;
    if (in.offsets_size() != codebook_size + 1) {
      fail(where + " has " + std::to_string(in.offsets_size()) + " offsets, expected codebook size + 1 = " +
           std::to_string(codebook_size + 1));
    }
    if (in.vectors_size() % 3 != 0) fail(where + " has a vote vector count not divisible by 3");
    table.offsets.assign(in.offsets().begin(), in.offsets().end());
    for (size_t i = 1; i < table.offsets.size(); ++i) {
      if (table.offsets[i] < table.offsets[i - 1]) fail(where + " offsets decrease at codeword " + std::to_string(i - 1));
    }
    if (table.offsets.front() != 0 || table.offsets.back() != static_cast<uint32_t>(in.vectors_size() / 3)) {
      fail(where + " offsets do not span its " + std::to_string(in.vectors_size() / 3) + " votes");
    }
    table.vectors.resize(static_cast<size_t>(in.vectors_size() / 3));
    for (size_t i = 0; i < table.vectors.size(); ++i) {
      table.vectors[i] = Eigen::Vector3f(in.vectors(3 * i), in.vectors(3 * i + 1), in.vectors(3 * i + 2));
    }
    if (in.heights_size() > 0) {
      if (static_cast<size_t>(in.heights_size()) != table.vectors.size()) {
        fail(where + " has " + std::to_string(in.heights_size()) + " vote heights for " +
             std::to_string(table.vectors.size()) + " votes");
      }
      table.heights.assign(in.heights().begin(), in.heights().end());
      // Recognition finds a keypoint's votes by binary search over each codeword's heights.
      for (size_t c = 0; c + 1 < table.offsets.size(); ++c) {
        const auto first = table.heights.begin() + table.offsets[c], last = table.heights.begin() + table.offsets[c + 1];
        if (!std::all_of(first, last, [](float h) { return std::isfinite(h); }) || !std::is_sorted(first, last)) {
          fail(where + " vote heights of codeword " + std::to_string(c) + " are not finite and ascending");
        }
      }
    }
    if (in.objects_size() > 0 || in.headings_size() > 0) {
      if (static_cast<size_t>(in.objects_size()) != table.vectors.size() ||
          static_cast<size_t>(in.headings_size()) != table.vectors.size()) {
        fail(where + " has " + std::to_string(in.objects_size()) + " vote objects and " +
             std::to_string(in.headings_size()) + " headings for " + std::to_string(table.vectors.size()) + " votes");
      }
      for (uint32_t o : in.objects()) {
        if (o >= objects) fail(where + " has a vote of training object " + std::to_string(o) + " of " + std::to_string(objects));
      }
      for (float h : in.headings()) {
        if (!std::isfinite(h)) fail(where + " has a heading that is not finite");
      }
      table.objects.assign(in.objects().begin(), in.objects().end());
      table.headings.assign(in.headings().begin(), in.headings().end());
    }
    if (in.codeword_weights_size() > 0) {
      if (in.codeword_weights_size() != codebook_size) {
        fail(where + " has " + std::to_string(in.codeword_weights_size()) + " codeword weights for " +
             std::to_string(codebook_size) + " codewords");
      }
      for (float w : in.codeword_weights()) {
        if (!(w > 0 && w <= 1)) fail(where + " has a codeword weight outside (0, 1]");
      }
      table.codeword_weights.assign(in.codeword_weights().begin(), in.codeword_weights().end());
    }
    return table;
  }

  GravityParams gravity(const v1::FrontEndParams& fe) const {
    GravityParams g;
    if (!fe.has_gravity()) {
      g.enabled = false;  // trained before the gravity stage existed
      return g;
    }
    const v1::GravityParams& in = fe.gravity();
    g.enabled = in.enabled();
    g.max_tilt_deg = in.max_tilt_deg();
    g.given_up_tolerance_deg = in.given_up_tolerance_deg();
    g.inlier_distance = in.inlier_distance();
    g.noise_sigmas = in.noise_sigmas();
    g.min_floor_fraction = in.min_floor_fraction();
    g.max_below_fraction = in.max_below_fraction();
    g.below_margin = in.below_margin();
    g.wall_min_height = in.wall_min_height();
    g.wall_min_width = in.wall_min_width();
    g.wall_tilt_deg = in.wall_tilt_deg();
    g.max_walls = in.max_walls();
    g.iterations = in.iterations();
    g.sample_points = in.sample_points();
    g.seed = in.seed();
    g.wall_cell = in.wall_cell();
    g.wall_max_seen_through = in.wall_max_seen_through();
    if (in.has_given_up_kept_deg()) g.given_up_kept_deg = in.given_up_kept_deg();
    const bool valid = g.wall_cell >= 0 && g.wall_cell <= 10 && g.wall_max_seen_through >= 0 &&
                       g.wall_max_seen_through <= 1000 && g.max_tilt_deg >= 0 && g.max_tilt_deg <= 90 &&
                       g.given_up_tolerance_deg >= 0 && g.given_up_tolerance_deg <= 90 && g.given_up_kept_deg >= 0 &&
                       g.given_up_kept_deg <= 90 && g.inlier_distance > 0 && std::isfinite(g.inlier_distance) &&
                       g.noise_sigmas >= 0 && g.min_floor_fraction >= 0 && g.min_floor_fraction <= 1 &&
                       g.max_below_fraction >= 0 && g.max_below_fraction <= 1 && g.below_margin >= 0 &&
                       g.wall_min_height >= 0 && g.wall_min_width >= 0 && g.wall_tilt_deg >= 0 &&
                       g.wall_tilt_deg <= 90 && g.max_walls >= 0 && g.max_walls <= 64 && g.iterations >= 1 &&
                       g.iterations <= 100000 && g.sample_points >= 3 && g.sample_points <= 10000000;
    if (g.enabled && !valid) fail("front-end gravity parameters are out of range");
    return g;
  }

  VotingParams voting(const v1::ModelData& in) const {
    VotingParams v;
    switch (in.voting().frame()) {
      case v1::VOTE_FRAME_UNSPECIFIED:
      case v1::VOTE_FRAME_LRF:
        v.frame = VoteFrame::kLrf;
        break;
      case v1::VOTE_FRAME_UPRIGHT:
        v.frame = VoteFrame::kUpright;
        break;
      default:
        fail("voting parameters have unknown vote frame " + std::to_string(in.voting().frame()));
    }
    v.height_tolerance = in.voting().height_tolerance();
    if (!(v.height_tolerance >= 0 && std::isfinite(v.height_tolerance))) {
      fail("voting height_tolerance " + std::to_string(v.height_tolerance) + " is not >= 0");
    }
    v.height_normalized = in.voting().height_normalized();
    return v;
  }

  ActivationParams activation(const v1::ActivationParams& in, const std::string& where) const {
    ActivationParams out;
    out.strategy = strategy(in.strategy(), where);
    out.k = in.k();
    out.cutoff = in.cutoff();
    return out;
  }

  ActivationStrategy strategy(int v, const std::string& where) const {
    if (const auto strategy = wire::activationStrategyFromProto(v)) return *strategy;
    fail(where + " has unknown activation strategy " + std::to_string(v));
  }

  CodebookType codebookType(int v, const std::string& where) const {
    if (const auto type = wire::codebookTypeFromProto(v)) return *type;
    fail(where + " has unknown codebook type " + std::to_string(v));
  }

  VoteWeighting weighting(int v, const std::string& where) const {
    if (const auto weighting = wire::voteWeightingFromProto(v)) return *weighting;
    fail(where + " has unknown vote weighting " + std::to_string(v));
  }

 private:
  std::string source_;
};

Model fromProto(const v1::ModelData& in, const std::string& source) {
  const Reader r(source);
  Model m;
  const auto& fe = in.front_end();
  m.front_end.downsample.leaf_size = fe.leaf_size();
  m.front_end.smoothing.enabled = fe.smoothing_enabled();
  m.front_end.smoothing.radius = fe.smoothing_radius();
  m.front_end.smoothing.polynomial_order = fe.smoothing_polynomial_order();
  m.front_end.normals.radius = fe.normal_radius();
  m.front_end.keypoints.radius = fe.boundary_radius();
  m.front_end.keypoints.angle_threshold = fe.boundary_angle_threshold();
  m.front_end.shot.radius = fe.shot_radius();
  m.front_end.shot.min_neighbours = fe.shot_min_neighbours();
  switch (fe.keypoint_method()) {
    case v1::FrontEndParams::KEYPOINT_METHOD_UNSPECIFIED:  // written before contours existed
    case v1::FrontEndParams::KEYPOINT_METHOD_BOUNDARY:
      m.front_end.keypoints.method = KeypointMethod::kBoundary;
      break;
    case v1::FrontEndParams::KEYPOINT_METHOD_AUTO:
      m.front_end.keypoints.method = KeypointMethod::kAuto;
      break;
    case v1::FrontEndParams::KEYPOINT_METHOD_OCCLUDING_CONTOUR:
      m.front_end.keypoints.method = KeypointMethod::kOccludingContour;
      break;
    case v1::FrontEndParams::KEYPOINT_METHOD_RANGE_IMAGE:
      m.front_end.keypoints.method = KeypointMethod::kRangeImage;
      break;
    default:
      r.fail("front-end parameters have unknown keypoint_method " + std::to_string(fe.keypoint_method()));
  }
  auto& keypoints = m.front_end.keypoints;
  switch (fe.unorganized_keypoint_method()) {
    case v1::FrontEndParams::KEYPOINT_METHOD_UNSPECIFIED:  // written before range images
    case v1::FrontEndParams::KEYPOINT_METHOD_BOUNDARY:
      keypoints.unorganized = KeypointMethod::kBoundary;
      break;
    case v1::FrontEndParams::KEYPOINT_METHOD_RANGE_IMAGE:
      keypoints.unorganized = KeypointMethod::kRangeImage;
      keypoints.range_image.pixel_spacings = fe.range_image_pixel_spacings();
      keypoints.range_image.max_pixels = static_cast<long>(fe.range_image_max_pixels());
      if (!(keypoints.range_image.pixel_spacings > 0 && std::isfinite(keypoints.range_image.pixel_spacings) &&
            keypoints.range_image.max_pixels >= 9)) {
        r.fail("front-end range image parameters are invalid: pixel_spacings " +
               std::to_string(keypoints.range_image.pixel_spacings) + ", max_pixels " +
               std::to_string(keypoints.range_image.max_pixels));
      }
      break;
    default:
      r.fail("front-end parameters have an unorganized_keypoint_method that is not BOUNDARY or RANGE_IMAGE: " +
             std::to_string(fe.unorganized_keypoint_method()));
  }
  auto& contour = m.front_end.keypoints.contour;
  contour.window = fe.contour_window();
  contour.min_jump = fe.contour_min_jump();
  contour.relative_jump = fe.contour_relative_jump();
  contour.max_gap = fe.contour_max_gap();
  m.front_end.keypoints.min_spacing = fe.keypoint_min_spacing();
  m.front_end.keypoints.surface_spacing = fe.keypoint_surface_spacing();
  if (m.front_end.keypoints.method != KeypointMethod::kBoundary &&
      !(contour.window >= 1 && contour.max_gap >= contour.window && contour.min_jump > 0 &&
        contour.relative_jump >= 0 && std::isfinite(contour.relative_jump))) {
    r.fail("front-end contour parameters are invalid: window " + std::to_string(contour.window) + ", max_gap " +
           std::to_string(contour.max_gap) + ", min_jump " + std::to_string(contour.min_jump) + ", relative_jump " +
           std::to_string(contour.relative_jump));
  }
  if (!(m.front_end.keypoints.min_spacing >= 0 && std::isfinite(m.front_end.keypoints.min_spacing))) {
    r.fail("front-end keypoint_min_spacing " + std::to_string(m.front_end.keypoints.min_spacing) + " is not >= 0");
  }
  if (!(m.front_end.keypoints.surface_spacing >= 0 && std::isfinite(m.front_end.keypoints.surface_spacing))) {
    r.fail("front-end keypoint_surface_spacing " + std::to_string(m.front_end.keypoints.surface_spacing) +
           " is not >= 0");
  }
  if (!(fe.leaf_size() > 0) || !(fe.normal_radius() > 0) || !(fe.boundary_radius() > 0) || !(fe.shot_radius() > 0)) {
    r.fail("front-end parameters have a non-positive radius or leaf size");
  }
  m.front_end.gravity = r.gravity(fe);
  m.voting = r.voting(in);
  if (m.voting.frame == VoteFrame::kUpright && !m.front_end.gravity.enabled) {
    r.fail("upright vote frames need the gravity stage, which the front-end parameters turn off");
  }
  m.trained_knn = r.activation(in.trained_knn(), "trained_knn");
  m.trained_cutoff = r.activation(in.trained_cutoff(), "trained_cutoff");
  if (in.global_codebook().size() > 0) m.global_codebook = r.codebook(in.global_codebook(), "global codebook");
  const int dim = m.global_codebook ? m.global_codebook->dim() : -1;

  if (in.categories_size() == 0) r.fail("the model has no categories");
  std::set<std::string> names;
  for (const auto& c : in.categories()) {
    const std::string where = "category '" + c.name() + "'";
    if (c.name().empty()) r.fail("a category has an empty name");
    if (!names.insert(c.name()).second) r.fail(where + " appears twice");
    if (!(c.bin_size() > 0)) r.fail(where + " has bin size " + std::to_string(c.bin_size()));
    CategoryModel cat;
    cat.name = c.name();
    cat.bin_size = c.bin_size();
    const auto& b = c.box();
    cat.box = {b.min_volume(), b.max_volume(), b.max_edge(), b.mean_volume(), b.std_volume(), b.mean_max_edge(),
               b.std_max_edge()};
    for (const auto& o : c.objects()) {
      TrainingObject object{{o.width(), o.depth(), o.height()}, o.center_height(), {}, o.size_guessed()};
      if (!(object.size.allFinite() && (object.size.array() > 0).all() && std::isfinite(object.center_height))) {
        r.fail(where + " has a training object with a size that is not positive");
      }
      if (o.surface_size() % 3 != 0) r.fail(where + " has a training shape whose coordinates are not x, y, z triples");
      for (int i = 0; i + 2 < o.surface_size(); i += 3) {
        const Eigen::Vector3f p(o.surface(i), o.surface(i + 1), o.surface(i + 2));
        if (!p.allFinite()) r.fail(where + " has a training shape point that is not finite");
        object.surface.push_back(p);
      }
      cat.objects.push_back(object);
    }
    if (c.own_codebook().size() > 0) {
      cat.own_codebook = r.codebook(c.own_codebook(), where + " codebook");
      if (dim >= 0 && cat.own_codebook->dim() != dim) r.fail(where + " codebook dimension differs from the global one");
      cat.own_votes = r.votes(c.own_votes(), cat.own_codebook->size(), cat.objects.size(), where + " own votes");
    } else if (c.own_votes().vectors_size() > 0) {
      r.fail(where + " has separated votes but no separated codebook");
    }
    if (m.global_codebook) {
      cat.global_votes = r.votes(c.global_votes(), m.global_codebook->size(), cat.objects.size(), where + " global votes");
    } else if (c.global_votes().vectors_size() > 0) {
      r.fail(where + " has global votes but the model has no global codebook");
    }
    for (const auto& t : c.thresholds()) {
      const ThresholdKey key{r.codebookType(t.codebook(), where + " threshold"),
                             r.strategy(t.activation(), where + " threshold"),
                             r.weighting(t.weighting(), where + " threshold")};
      cat.thresholds[key] = t.value();
      if (t.has_mean() && t.has_std()) cat.threshold_stats[key] = {t.mean(), t.std()};
    }
    if (c.has_calibration()) cat.calibration = r.calibration(c.calibration(), where);
    if (c.has_cloud_calibration()) cat.cloud_calibration = r.calibration(c.cloud_calibration(), where + " (clouds)");
    cat.training_models = c.training_models();
    cat.training_scans = c.training_scans();
    m.categories.push_back(std::move(cat));
  }
  const auto& p = in.provenance();
  m.provenance.meshes.assign(p.meshes().begin(), p.meshes().end());
  m.provenance.scans = p.scans();
  m.provenance.created = p.created();
  m.provenance.code_version = p.code_version();
  m.provenance.command = p.command();
  for (int d = 0; d < in.draws_size(); ++d) {
    const std::string draw = source + " (draw " + std::to_string(d + 2) + ")";
    if (in.draws(d).draws_size() > 0) r.fail("draw " + std::to_string(d + 2) + " has draws of its own");
    Model other = fromProto(in.draws(d), draw);
    if (!sameFrontEnd(m, other)) r.fail("draw " + std::to_string(d + 2) + " has another front end than the first");
    if (!m.sameCategories(other)) r.fail("draw " + std::to_string(d + 2) + " has other categories than the first");
    m.draws.push_back(std::move(other));
  }
  return m;
}

void toProto(const FrontEndParams& in, v1::FrontEndParams* out) {
  out->set_leaf_size(in.downsample.leaf_size);
  out->set_smoothing_enabled(in.smoothing.enabled);
  out->set_smoothing_radius(in.smoothing.radius);
  out->set_smoothing_polynomial_order(in.smoothing.polynomial_order);
  out->set_normal_radius(in.normals.radius);
  out->set_boundary_radius(in.keypoints.radius);
  out->set_boundary_angle_threshold(in.keypoints.angle_threshold);
  out->set_shot_radius(in.shot.radius);
  out->set_shot_min_neighbours(in.shot.min_neighbours);
  switch (in.keypoints.method) {
    case KeypointMethod::kAuto:
      out->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_AUTO);
      break;
    case KeypointMethod::kBoundary:
      out->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_BOUNDARY);
      break;
    case KeypointMethod::kOccludingContour:
      out->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_OCCLUDING_CONTOUR);
      break;
    case KeypointMethod::kRangeImage:
      out->set_keypoint_method(v1::FrontEndParams::KEYPOINT_METHOD_RANGE_IMAGE);
      break;
  }
  out->set_unorganized_keypoint_method(in.keypoints.unorganized == KeypointMethod::kRangeImage
                                          ? v1::FrontEndParams::KEYPOINT_METHOD_RANGE_IMAGE
                                          : v1::FrontEndParams::KEYPOINT_METHOD_BOUNDARY);
  out->set_range_image_pixel_spacings(in.keypoints.range_image.pixel_spacings);
  out->set_range_image_max_pixels(in.keypoints.range_image.max_pixels);
  out->set_contour_window(in.keypoints.contour.window);
  out->set_contour_min_jump(in.keypoints.contour.min_jump);
  out->set_contour_relative_jump(in.keypoints.contour.relative_jump);
  out->set_contour_max_gap(in.keypoints.contour.max_gap);
  out->set_keypoint_min_spacing(in.keypoints.min_spacing);
  out->set_keypoint_surface_spacing(in.keypoints.surface_spacing);
  toProto(in.gravity, out->mutable_gravity());
}

}  // namespace

bool sameFrontEnd(const Model& a, const Model& b) {
  v1::FrontEndParams pa, pb;
  toProto(a.front_end, &pa);
  toProto(b.front_end, &pb);
  return pa.SerializeAsString() == pb.SerializeAsString();
}

namespace {

void toProto(const Model& model, v1::ModelData& data) {
  auto* fe = data.mutable_front_end();
  toProto(model.front_end, fe);
  data.mutable_voting()->set_frame(model.voting.frame == VoteFrame::kLrf ? v1::VOTE_FRAME_LRF : v1::VOTE_FRAME_UPRIGHT);
  data.mutable_voting()->set_height_tolerance(model.voting.height_tolerance);
  data.mutable_voting()->set_height_normalized(model.voting.height_normalized);
  toProto(model.trained_knn, data.mutable_trained_knn());
  toProto(model.trained_cutoff, data.mutable_trained_cutoff());
  if (model.global_codebook) toProto(*model.global_codebook, data.mutable_global_codebook());
  for (const auto& c : model.categories) {
    auto* out = data.add_categories();
    out->set_name(c.name);
    out->set_bin_size(c.bin_size);
    auto* b = out->mutable_box();
    b->set_min_volume(c.box.min_volume);
    b->set_max_volume(c.box.max_volume);
    b->set_max_edge(c.box.max_edge);
    b->set_mean_volume(c.box.mean_volume);
    b->set_std_volume(c.box.std_volume);
    b->set_mean_max_edge(c.box.mean_max_edge);
    b->set_std_max_edge(c.box.std_max_edge);
    if (c.own_codebook) toProto(*c.own_codebook, out->mutable_own_codebook());
    toProto(c.global_votes, out->mutable_global_votes());
    toProto(c.own_votes, out->mutable_own_votes());
    for (const auto& [key, value] : c.thresholds) {
      auto* t = out->add_thresholds();
      t->set_codebook(wire::toProto(key.codebook));
      t->set_activation(wire::toProto(key.activation));
      t->set_weighting(wire::toProto(key.weighting));
      t->set_value(value);
      if (const auto stats = c.threshold_stats.find(key); stats != c.threshold_stats.end()) {
        t->set_mean(stats->second.mean);
        t->set_std(stats->second.std);
      }
    }
    for (const auto& o : c.objects) {
      auto* object = out->add_objects();
      object->set_width(o.size.x());
      object->set_depth(o.size.y());
      object->set_height(o.size.z());
      object->set_center_height(o.center_height);
      object->set_size_guessed(o.size_guessed);
      for (const auto& p : o.surface) {
        object->add_surface(p.x());
        object->add_surface(p.y());
        object->add_surface(p.z());
      }
    }
    if (c.calibration) writeCalibration(*c.calibration, out->mutable_calibration());
    if (c.cloud_calibration) writeCalibration(*c.cloud_calibration, out->mutable_cloud_calibration());
    out->set_training_models(c.training_models);
    out->set_training_scans(c.training_scans);
  }
  auto* p = data.mutable_provenance();
  for (const auto& mesh : model.provenance.meshes) p->add_meshes(mesh);
  p->set_scans(model.provenance.scans);
  p->set_created(model.provenance.created);
  p->set_code_version(model.provenance.code_version);
  p->set_command(model.provenance.command);
  for (const auto& draw : model.draws) toProto(draw, *data.add_draws());
}

}  // namespace

std::string serializeModel(const Model& model) {
  v1::ModelData data;
  toProto(model, data);
  v1::ModelFile file;
  file.set_magic(kMagic);
  file.set_format_version(kModelFormatVersion);
  if (!data.SerializeToString(file.mutable_payload())) {
    throw Error(ErrorCode::kInternal, "model serialization failed (payload over 2 GB?)");
  }
  file.set_payload_crc32(crc32Of(file.payload()));
  return file.SerializeAsString();
}

ModelFileContents parseModelFile(const std::string& bytes, const std::string& source) {
  const Reader r(source);
  v1::ModelFile file;
  if (!file.ParseFromString(bytes)) r.fail("not a model file or truncated (the ModelFile envelope does not parse)");
  // What the file holds instead is not echoed: it may be any file the server can read.
  if (file.magic() != kMagic) r.fail(std::string("wrong magic: not a model file (they start with '") + kMagic + "')");
  if (file.format_version() == 0 || file.format_version() > kModelFormatVersion) {
    r.fail("format version " + std::to_string(file.format_version()) + " is not supported (this build reads 1.." +
           std::to_string(kModelFormatVersion) + ")");
  }
  if (crc32Of(file.payload()) != file.payload_crc32()) {
    r.fail("CRC-32 mismatch (the file is truncated or damaged)");
  }
  ModelFileContents out;
  if (!out.description.ParseFromString(file.payload())) r.fail("the payload does not parse as ModelData");
  out.model = fromProto(out.description, source);
  out.format_version = file.format_version();
  char version[9];
  std::snprintf(version, sizeof version, "%08x", crc32Of(bytes));
  out.version = version;
  const auto describe = [](v1::ModelData& d) {
    if (d.has_global_codebook()) d.mutable_global_codebook()->clear_centers();
    for (auto& category : *d.mutable_categories()) {
      if (category.has_own_codebook()) category.mutable_own_codebook()->clear_centers();
      category.clear_global_votes();
      category.clear_own_votes();
    }
  };
  describe(out.description);
  for (auto& draw : *out.description.mutable_draws()) describe(draw);
  return out;
}

Model parseModel(const std::string& bytes, const std::string& source) {
  return std::move(parseModelFile(bytes, source).model);
}

ModelFileContents readModelFile(const std::string& path, size_t max_bytes) {
  struct File {
    int fd;
    ~File() {
      if (fd >= 0) ::close(fd);
    }
  };
  // O_NONBLOCK: opening a FIFO must not wait for a writer; fstat then refuses it.
  const File file{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  struct stat status {};
  if (file.fd < 0 || ::fstat(file.fd, &status) != 0 || !S_ISREG(status.st_mode)) {
    throw Error(ErrorCode::kNotFound, path + ": not a readable regular file");
  }
  const Error too_large(ErrorCode::kResourceExhausted,
                        path + ": larger than the " + std::to_string(max_bytes) + " bytes a model file may have here");
  if (static_cast<uint64_t>(status.st_size) > max_bytes) throw too_large;
  // One byte more than the limit allows tells a file that grew past it while being read.
  std::string bytes(std::min<uint64_t>(static_cast<uint64_t>(status.st_size), max_bytes) + 1, '\0');
  size_t size = 0;
  while (size < bytes.size()) {
    const ssize_t n = ::read(file.fd, bytes.data() + size, bytes.size() - size);
    if (n == 0) break;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(ErrorCode::kIo, path + ": read failed: " + std::strerror(errno));
    size += static_cast<size_t>(n);
    if (size == bytes.size() && size <= max_bytes) bytes.resize(std::min(max_bytes + 1, 2 * bytes.size()));
  }
  if (size > max_bytes) throw too_large;
  bytes.resize(size);
  return parseModelFile(bytes, path);
}

void saveModel(const Model& model, const std::string& path) {
  const std::string bytes = serializeModel(model);
  // Written next to the target and renamed, so a crash never leaves a half-written model.
  const std::string temporary = path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(ErrorCode::kIo, "cannot write model file " + temporary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out.flush()) throw Error(ErrorCode::kIo, "cannot write model file " + temporary);
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    std::remove(temporary.c_str());
    throw Error(ErrorCode::kIo, "cannot rename " + temporary + " to " + path);
  }
}

Model loadModel(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(ErrorCode::kNotFound, "model file " + path + " does not exist or cannot be opened");
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (in.bad()) throw Error(ErrorCode::kIo, "cannot read model file " + path);
  return parseModel(bytes.str(), path);
}

}  // namespace ism
