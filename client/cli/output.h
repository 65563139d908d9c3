#pragma once
// Human-readable tables and JSON (the canonical proto3 JSON mapping) of service answers.
#include <google/protobuf/message.h>

#include <ostream>
#include <string>

#include "core/common/gravity_frame.h"
#include "ism/v1/service.pb.h"

namespace ism::client {

std::string toJson(const google::protobuf::Message& message);  // one line

// "up: (0.00, 0.00, 1.00) floor, floor at 0.00 m (5120 points)".
std::string gravityLine(const Gravity& gravity);
void printResult(std::ostream& out, const std::string& title, const v1::RecognitionResult& result);
void printModelList(std::ostream& out, const v1::ListModelsResponse& models);
void printModel(std::ostream& out, const v1::ModelInfo& model);

}  // namespace ism::client
