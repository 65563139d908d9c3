#pragma once
// A trained set of Implicit Shape Models: the front end it was trained with, the codebook(s),
// per category the votes stored under each codeword, detection thresholds and box statistics.
// Saved as the versioned Protobuf format of proto/ism/v1/model.proto (model_file.h).
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/frontend/params.h"

namespace ism {

enum class CodebookType { kGlobal, kSeparated };
enum class VoteWeighting {
  kCategorization,  // CW: every vote weighs 1
  kLocalization,    // LW: 1/M * 1/|Occ[i]|, each keypoint's votes sum to 1
  kActivation,      // AW: (1 - d/2) * LW
};

const char* toString(CodebookType t);
const char* toString(ActivationStrategy s);
const char* toString(VoteWeighting w);
// Short names used by CLIs and the service: "global"/"separated", "knn"/"cutoff", "cw"/"lw"/"aw".
CodebookType parseCodebookType(const std::string& s);
ActivationStrategy parseActivationStrategy(const std::string& s);
VoteWeighting parseVoteWeighting(const std::string& s);

// The strategy of one recognition call (the seed compares these combinations).
struct Strategy {
  CodebookType codebook = CodebookType::kGlobal;
  ActivationParams activation;
  VoteWeighting weighting = VoteWeighting::kLocalization;
};

struct ThresholdKey {
  CodebookType codebook;
  ActivationStrategy activation;
  VoteWeighting weighting;
  bool operator<(const ThresholdKey& o) const {
    return std::tie(codebook, activation, weighting) < std::tie(o.codebook, o.activation, o.weighting);
  }
  bool operator==(const ThresholdKey& o) const {
    return codebook == o.codebook && activation == o.activation && weighting == o.weighting;
  }
};

// Votes stored under each codeword, CSR layout: votes of codeword i are
// vectors[offsets[i] .. offsets[i+1]), each in the LRF of the keypoint that cast it.
struct VoteTable {
  std::vector<uint32_t> offsets;  // codebook size + 1 entries
  std::vector<Eigen::Vector3f> vectors;
  size_t occurrences(int codeword) const { return offsets[codeword + 1] - offsets[codeword]; }
  bool empty() const { return vectors.empty(); }
};

// Oriented-box limits learned from the training scans' keypoint boxes (mean -/+ std).
struct BoxStats {
  float min_volume = 0;
  float max_volume = 0;
  float max_edge = 0;
  // The raw statistics behind the limits, for reports.
  float mean_volume = 0, std_volume = 0, mean_max_edge = 0, std_max_edge = 0;
};

// Leave-one-out statistics behind a threshold: the held-out models' scores at their centres.
struct ThresholdStats {
  float mean = 0;
  float std = 0;
};

struct CategoryModel {
  std::string name;
  float bin_size = 0.1f;  // Hough bin edge (m)
  BoxStats box;
  std::optional<Codebook> own_codebook;  // separated codebook, when trained
  VoteTable global_votes;                // votes under the global codebook's codewords
  VoteTable own_votes;                   // votes under own_codebook's codewords
  std::map<ThresholdKey, float> thresholds;  // leave-one-out mean - std per combination, floored
  std::map<ThresholdKey, ThresholdStats> threshold_stats;  // behind `thresholds`; empty in older files
  int training_models = 0;
  int training_scans = 0;
};

struct Provenance {
  std::vector<std::string> meshes;  // "category<TAB>path<TAB>credit"
  int scans = 0;
  std::string created;       // ISO 8601 UTC
  std::string code_version;  // git describe of the training build
  std::string command;       // how it was trained
};

struct Model {
  FrontEndParams front_end;
  // Activation parameters the thresholds were computed with (kNN k and cutoff distance).
  ActivationParams trained_knn{ActivationStrategy::kKnn, 1, 0.25f};
  ActivationParams trained_cutoff{ActivationStrategy::kCutoff, 1, 0.25f};
  std::optional<Codebook> global_codebook;
  std::vector<CategoryModel> categories;
  Provenance provenance;

  const CategoryModel* find(const std::string& category) const;
  bool has(CodebookType type) const;
};

}  // namespace ism
