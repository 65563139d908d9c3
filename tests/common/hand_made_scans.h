#pragma once
// Hand-made training scans with exactly known leave-one-out answers, for the training stages.
#include <cstdlib>
#include <string>
#include <vector>

#include "core/recognition/box_selection.h"
#include "core/training/trainer.h"

namespace ism::testing {

constexpr int kKeypoints = 12;  // per scan, one per descriptor prototype
constexpr int kModels = 3;
constexpr int kScansPerModel = 4;

// Hand-made scans with exactly known leave-one-out answers: keypoint j of every scan of a
// category has the same descriptor prototype and the same pose relative to the object, only
// the whole object moves and turns between scans. Then codeword j holds identical votes, and a
// held-out scan's keypoint j gets (kModels - 1) * kScansPerModel CW votes, all at its centre.
// Model `odd_model` (if any) has the same descriptors but another keypoint geometry, as a
// dissimilar training model would: its votes miss the other models' centres and theirs miss its.
inline std::vector<TrainingScan> handMadeScans(const std::string& category, uint32_t seed, int odd_model = -1) {
  std::srand(seed);
  DescriptorMatrix prototypes = DescriptorMatrix::Random(kKeypoints, 16);
  prototypes.rowwise().normalize();
  std::vector<Eigen::Vector3f> offsets, odd_offsets;
  std::vector<Eigen::Matrix3f> lrfs;
  for (int j = 0; j < kKeypoints; ++j) {
    offsets.push_back(0.3f * Eigen::Vector3f::Random());
    odd_offsets.push_back(offsets.back() + Eigen::Vector3f(0.5f, 0, 0));
    lrfs.push_back(Eigen::Quaternionf::UnitRandom().toRotationMatrix());
  }
  std::vector<TrainingScan> scans;
  for (int m = 0; m < kModels; ++m) {
    for (int s = 0; s < kScansPerModel; ++s) {
      TrainingScan scan;
      scan.category = category;
      scan.model_index = m;
      scan.object_center = 2.0f * Eigen::Vector3f::Random();
      const Eigen::Matrix3f turn = Eigen::AngleAxisf(0.4f * s + m, Eigen::Vector3f::UnitZ()).toRotationMatrix();
      scan.features.descriptors = prototypes + 1e-3f * DescriptorMatrix::Random(kKeypoints, 16);
      for (int j = 0; j < kKeypoints; ++j) {
        const auto& offset = (m == odd_model ? odd_offsets : offsets)[static_cast<size_t>(j)];
        scan.features.positions.push_back(scan.object_center + turn * offset);
        scan.features.lrfs.push_back(lrfs[static_cast<size_t>(j)] * turn.transpose());
      }
      scan.keypoint_box = fitOrientedBox(scan.features.positions);
      scans.push_back(std::move(scan));
    }
  }
  return scans;
}

}  // namespace ism::testing
