#include "proto/wire/enums.h"

namespace ism::wire {

v1::CodebookType toProto(CodebookType type) {
  switch (type) {
    case CodebookType::kGlobal: return v1::CODEBOOK_TYPE_GLOBAL;
    case CodebookType::kSeparated: return v1::CODEBOOK_TYPE_SEPARATED;
  }
  return v1::CODEBOOK_TYPE_UNSPECIFIED;
}

v1::ActivationStrategy toProto(ActivationStrategy strategy) {
  switch (strategy) {
    case ActivationStrategy::kKnn: return v1::ACTIVATION_STRATEGY_KNN;
    case ActivationStrategy::kCutoff: return v1::ACTIVATION_STRATEGY_CUTOFF;
  }
  return v1::ACTIVATION_STRATEGY_UNSPECIFIED;
}

v1::VoteWeighting toProto(VoteWeighting weighting) {
  switch (weighting) {
    case VoteWeighting::kCategorization: return v1::VOTE_WEIGHTING_CATEGORIZATION;
    case VoteWeighting::kLocalization: return v1::VOTE_WEIGHTING_LOCALIZATION;
    case VoteWeighting::kActivation: return v1::VOTE_WEIGHTING_ACTIVATION;
  }
  return v1::VOTE_WEIGHTING_UNSPECIFIED;
}

std::optional<CodebookType> codebookTypeFromProto(int value) {
  switch (value) {
    case v1::CODEBOOK_TYPE_GLOBAL: return CodebookType::kGlobal;
    case v1::CODEBOOK_TYPE_SEPARATED: return CodebookType::kSeparated;
  }
  return std::nullopt;
}

std::optional<ActivationStrategy> activationStrategyFromProto(int value) {
  switch (value) {
    case v1::ACTIVATION_STRATEGY_KNN: return ActivationStrategy::kKnn;
    case v1::ACTIVATION_STRATEGY_CUTOFF: return ActivationStrategy::kCutoff;
  }
  return std::nullopt;
}

std::optional<VoteWeighting> voteWeightingFromProto(int value) {
  switch (value) {
    case v1::VOTE_WEIGHTING_CATEGORIZATION: return VoteWeighting::kCategorization;
    case v1::VOTE_WEIGHTING_LOCALIZATION: return VoteWeighting::kLocalization;
    case v1::VOTE_WEIGHTING_ACTIVATION: return VoteWeighting::kActivation;
  }
  return std::nullopt;
}

}  // namespace ism::wire
