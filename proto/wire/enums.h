#pragma once
// The enums of proto/ism/v1/model.proto and their core counterparts, mapped in one place: the
// model file (core/model/model_file.cc) and the service (server/, client/) both use these.
#include <optional>

#include "core/model/model.h"
#include "ism/v1/model.pb.h"

namespace ism::wire {

v1::CodebookType toProto(CodebookType type);
v1::ActivationStrategy toProto(ActivationStrategy strategy);
v1::VoteWeighting toProto(VoteWeighting weighting);

// nullopt for UNSPECIFIED and for numbers this build does not know: what that means (a default,
// a corrupt file) is the caller's to say.
std::optional<CodebookType> codebookTypeFromProto(int value);
std::optional<ActivationStrategy> activationStrategyFromProto(int value);
std::optional<VoteWeighting> voteWeightingFromProto(int value);

}  // namespace ism::wire
