#pragma once
// Human-readable tables and JSON (the canonical proto3 JSON mapping) of service answers.
#include <google/protobuf/message.h>

#include <ostream>
#include <string>

#include "ism/v1/service.pb.h"

namespace ism::client {

std::string toJson(const google::protobuf::Message& message);  // one line

void printResult(std::ostream& out, const std::string& title, const v1::RecognitionResult& result);
void printModelList(std::ostream& out, const v1::ListModelsResponse& models);
void printModel(std::ostream& out, const v1::ModelInfo& model);

}  // namespace ism::client
