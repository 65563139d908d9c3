#pragma once
// The mean and (population) standard deviation behind the learned limits: box sizes and
// leave-one-out thresholds are both mean -/+ std rules.
#include <cmath>
#include <vector>

namespace ism {

struct MeanStd {
  double mean = 0, std = 0;
};

// Zero for no values.
inline MeanStd meanStd(const std::vector<double>& values) {
  MeanStd r;
  if (values.empty()) return r;
  for (double v : values) r.mean += v;
  r.mean /= static_cast<double>(values.size());
  for (double v : values) r.std += (v - r.mean) * (v - r.mean);
  r.std = std::sqrt(r.std / static_cast<double>(values.size()));
  return r;
}

}  // namespace ism
