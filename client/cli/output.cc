#include "client/cli/output.h"

#include "core/report/report.h"
#include "proto/wire/messages.h"

#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <ctime>
#include <iomanip>

namespace ism::client {
namespace {

std::string localTime(int64_t unix_ms) {
  const std::time_t t = unix_ms / 1000;
  std::tm tm{};
  localtime_r(&t, &tm);
  std::ostringstream s;
  s << std::put_time(&tm, "%Y-%m-%d %H:%M:%S");
  return s.str();
}

std::string enumName(const google::protobuf::EnumDescriptor* descriptor, int value, const std::string& prefix) {
  const auto* v = descriptor->FindValueByNumber(value);
  if (v == nullptr) return std::to_string(value);
  std::string name = v->name();
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

}  // namespace

// Which up the boxes and height priors used, so that a caller can tell a found floor from a guess.
std::string gravityLine(const Gravity& g) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(2) << "up: (" << g.up.x() << ", " << g.up.y() << ", " << g.up.z() << ") "
    << toString(g.source);
  if (g.floor_level) {
    s << ", floor at " << *g.floor_level << " m (" << g.floor_points << " points)";
  } else {
    s << ", no floor found";
  }
  if (g.walls > 0) s << ", " << g.walls << " walls (" << g.wall_points << " points)";
  return s.str();
}

std::string toJson(const google::protobuf::Message& message) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  // Keep counts of zero and empty lists, so that scripts see every field.
  options.always_print_primitive_fields = true;
  google::protobuf::util::MessageToJsonString(message, &json, options);
  return json;
}

void printResult(std::ostream& out, const std::string& title, const v1::RecognitionResult& result) {
  out << title << ": " << result.hypotheses_size() << " hypotheses (model " << result.model_name() << "@"
      << result.model_version() << ", " << result.input_points() << " points, ";
  // Said only when it happened: dropped points usually mean a bad conversion upstream.
  if (result.out_of_range_points() > 0) out << result.out_of_range_points() << " out of sensor range dropped, ";
  out << result.keypoints() << " keypoints, " << std::fixed << std::setprecision(1) << result.total_ms() << " ms)\n";
  const RecognitionResult core = wire::resultFromProto(result);
  // The selection column only matters when the caller asked for boxes that fail the test.
  const bool any_failed = std::any_of(core.hypotheses.begin(), core.hypotheses.end(),
                                      [](const Hypothesis& h) { return !h.passed_selection; });
  out << hypothesesTable(core, any_failed);
  if (core.gravity) out << gravityLine(*core.gravity) << "\n";
  out << "stages:";
  for (const auto& t : result.timings()) out << " " << t.stage() << " " << std::setprecision(1) << t.ms() << " ms";
  out << "\n";
}

void printModelList(std::ostream& out, const v1::ListModelsResponse& models) {
  out << std::left << std::setw(16) << "name" << std::setw(10) << "version" << std::setw(8) << "format"
      << std::setw(21) << "loaded" << "categories\n";
  for (const auto& m : models.models()) {
    std::string categories;
    for (const auto& c : m.categories()) categories += (categories.empty() ? "" : ", ") + c.name();
    out << std::left << std::setw(16) << m.name() << std::setw(10) << m.version() << std::setw(8)
        << ("v" + std::to_string(m.format_version())) << std::setw(21) << localTime(m.loaded_at_unix_ms())
        << categories << "\n";
  }
}

void printModel(std::ostream& out, const v1::ModelInfo& m) {
  const auto& fe = m.front_end();
  out << "model " << m.name() << " (version " << m.version() << ", format v" << m.format_version() << ")\n"
      << "  file:       " << m.path() << "\n"
      << "  loaded:     " << localTime(m.loaded_at_unix_ms()) << " in " << std::fixed << std::setprecision(0)
      << m.load_ms() << " ms\n"
      << std::setprecision(3) << "  front end:  leaf " << fe.leaf_size() << " m, smoothing "
      << (fe.smoothing_enabled() ? "on" : "off") << " (r " << fe.smoothing_radius() << " m, order "
      << fe.smoothing_polynomial_order() << "), normals r " << fe.normal_radius() << " m, boundary r "
      << fe.boundary_radius() << " m / " << fe.boundary_angle_threshold() << " rad, SHOT r " << fe.shot_radius()
      << " m (min " << fe.shot_min_neighbours() << " neighbours)\n"
      << "  activation: kNN k=" << m.trained_knn().k() << ", cutoff " << m.trained_cutoff().cutoff() << "\n"
      << "  codebook:   global " << m.global_codebook_size() << " codewords\n"
      << "  draws:      " << m.draws() << " (recognised together)\n";
  const auto& p = m.provenance();
  out << "  provenance: " << p.meshes_size() << " meshes, " << p.scans() << " scans, created " << p.created()
      << " by " << p.code_version() << "\n";
  if (!p.command().empty()) out << "              " << p.command() << "\n";
  for (const auto& c : m.categories()) {
    const auto& box = c.box();
    out << "  category " << c.name() << ": bin " << c.bin_size() << " m, " << c.training_models() << " models / "
        << c.training_scans() << " scans, own codebook " << c.own_codebook_size() << ", votes " << c.global_votes()
        << " global / " << c.own_votes() << " own\n"
        << "    box: volume " << box.min_volume() << " .. " << box.max_volume() << " m^3, longest edge <= "
        << box.max_edge() << " m\n";
    for (const auto& t : c.thresholds()) {
      out << "    threshold " << std::left << std::setw(10)
          << enumName(v1::CodebookType_descriptor(), t.codebook(), "CODEBOOK_TYPE_") << std::setw(7)
          << enumName(v1::ActivationStrategy_descriptor(), t.activation(), "ACTIVATION_STRATEGY_") << std::setw(16)
          << enumName(v1::VoteWeighting_descriptor(), t.weighting(), "VOTE_WEIGHTING_") << std::right << t.value()
          << "\n";
    }
  }
}

}  // namespace ism::client
