#include "core/model/model.h"

#include <algorithm>
#include <cmath>

#include "core/common/error.h"

namespace ism {

const char* toString(CodebookType t) { return t == CodebookType::kGlobal ? "global" : "separated"; }

const char* toString(ActivationStrategy s) { return s == ActivationStrategy::kKnn ? "knn" : "cutoff"; }

const char* toString(VoteWeighting w) {
  switch (w) {
    case VoteWeighting::kCategorization: return "cw";
    case VoteWeighting::kLocalization: return "lw";
    case VoteWeighting::kActivation: return "aw";
  }
  return "?";
}

float Calibration::confidence(float score, int support, float fit, float profile_distance) const {
  const double s = std::max(static_cast<double>(score), 1e-12);
  const double logit = a * std::log(s) + c * std::log(s / std::max(support, 1)) + d * fit + e * profile_distance + b;
  return static_cast<float>(1.0 / (1.0 + std::exp(-logit)));
}

const char* toString(VoteFrame f) { return f == VoteFrame::kLrf ? "lrf" : "upright"; }

CodebookType parseCodebookType(const std::string& s) {
  if (s == "global") return CodebookType::kGlobal;
  if (s == "separated") return CodebookType::kSeparated;
  throw Error(ErrorCode::kInvalidInput, "unknown codebook type '" + s + "' (expected global or separated)");
}

ActivationStrategy parseActivationStrategy(const std::string& s) {
  if (s == "knn") return ActivationStrategy::kKnn;
  if (s == "cutoff") return ActivationStrategy::kCutoff;
  throw Error(ErrorCode::kInvalidInput, "unknown activation strategy '" + s + "' (expected knn or cutoff)");
}

VoteWeighting parseVoteWeighting(const std::string& s) {
  if (s == "cw") return VoteWeighting::kCategorization;
  if (s == "lw") return VoteWeighting::kLocalization;
  if (s == "aw") return VoteWeighting::kActivation;
  throw Error(ErrorCode::kInvalidInput, "unknown vote weighting '" + s + "' (expected cw, lw or aw)");
}

const CategoryModel* Model::find(const std::string& category) const {
  for (const auto& c : categories) {
    if (c.name == category) return &c;
  }
  return nullptr;
}

bool Model::sameCategories(const Model& other) const {
  return std::equal(categories.begin(), categories.end(), other.categories.begin(), other.categories.end(),
                    [](const CategoryModel& a, const CategoryModel& b) { return a.name == b.name; });
}

bool Model::has(CodebookType type) const {
  if (categories.empty()) return false;
  if (type == CodebookType::kGlobal) return global_codebook.has_value() && global_codebook->size() > 0;
  for (const auto& c : categories) {
    if (!c.own_codebook || c.own_codebook->size() == 0) return false;
  }
  return true;
}

void Model::trustGivenUp() {
  // The floor is searched within given_up_tolerance_deg of a given up, so no floor found is
  // farther from it than 90 deg.
  front_end.gravity.given_up_kept_deg = 90;
  for (Model& draw : draws) draw.trustGivenUp();
}

}  // namespace ism
