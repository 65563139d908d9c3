#include "core/training/discriminative_weights.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>

#include "core/common/error.h"
#include "core/training/newton.h"

namespace ism {
namespace {

constexpr int kInputs = 5;  // 1, ln s, ln(s / support), fit, profile distance; then the codewords

double logLoss(double z, double y) { return std::log1p(std::exp(-std::abs(z))) + std::max(z, 0.0) - y * z; }

void design(const std::vector<const CalibrationSample*>& rows, int codewords, Eigen::MatrixXd& x, Eigen::VectorXd& y) {
  x = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()), kInputs + codewords);
  y.resize(static_cast<Eigen::Index>(rows.size()));
  for (size_t i = 0; i < rows.size(); ++i) {
    const CalibrationSample& s = *rows[i];
    const auto r = static_cast<Eigen::Index>(i);
    x(r, 0) = 1;
    x.block<1, kInputs - 1>(r, 1) = calibrationInputs(s).transpose();
    for (const int c : s.codewords) {
      if (c >= 0 && c < codewords) x(r, kInputs + c) += 1.0 / static_cast<double>(s.codewords.size());
    }
    y[r] = s.positive ? 1.0 : 0.0;
  }
}

// The ridge on the codewords' slopes; the calibration inputs get the calibration's little one.
Eigen::VectorXd ridgeOf(int codewords, double codeword_ridge) {
  Eigen::VectorXd r = Eigen::VectorXd::Constant(kInputs + codewords, codeword_ridge);
  r[0] = 0;
  r.segment(1, kInputs - 1).setConstant(1e-3);
  return r;
}

// The summed log-loss on each fold's rows of the fit on the other folds' rows (the first `inputs`
// columns of the design `x`, labels `y`; `folds` each row's fold).
double heldOutLoss(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const std::vector<int>& folds, Eigen::Index inputs,
                   const Eigen::VectorXd& ridge) {
  double total = 0;
  for (const int fold : std::set<int>(folds.begin(), folds.end())) {
    std::vector<Eigen::Index> train, test;
    for (size_t i = 0; i < folds.size(); ++i) (folds[i] == fold ? test : train).push_back(static_cast<Eigen::Index>(i));
    if (train.empty() || test.empty()) continue;
    const Eigen::VectorXd w = ridgeLogistic(x(train, Eigen::seqN(0, inputs)), y(train), ridge.head(inputs));
    const Eigen::VectorXd z = x(test, Eigen::seqN(0, inputs)) * w;
    for (Eigen::Index i = 0; i < z.size(); ++i) total += logLoss(z[i], y[test[static_cast<size_t>(i)]]);
  }
  return total;
}

}  // namespace

Eigen::VectorXd ridgeLogistic(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& ridge) {
  if (x.rows() != y.size() || x.cols() != ridge.size()) {
    throw Error(ErrorCode::kInvalidInput, "ridgeLogistic: " + std::to_string(x.rows()) + " x " + std::to_string(x.cols()) +
                                              " inputs for " + std::to_string(y.size()) + " labels and " +
                                              std::to_string(ridge.size()) + " ridges");
  }
  const auto loss = [&](const Eigen::VectorXd& v) {
    const Eigen::VectorXd z = x * v;
    double sum = 0.5 * v.dot(ridge.cwiseProduct(v));
    for (Eigen::Index i = 0; i < z.size(); ++i) sum += logLoss(z[i], y[i]);
    return sum;
  };
  const auto derivatives = [&](const Eigen::VectorXd& v, Eigen::VectorXd& gradient, Eigen::MatrixXd& hessian) {
    const Eigen::VectorXd z = x * v;
    Eigen::VectorXd residual(z.size()), curvature(z.size());
    for (Eigen::Index i = 0; i < z.size(); ++i) {
      const double p = 1.0 / (1.0 + std::exp(-z[i]));
      residual[i] = p - y[i];
      curvature[i] = std::max(p * (1 - p), 1e-12);
    }
    gradient = x.transpose() * residual + ridge.cwiseProduct(v);
    hessian = x.transpose() * curvature.asDiagonal() * x;
    hessian.diagonal() += ridge + Eigen::VectorXd::Constant(ridge.size(), 1e-9);
  };
  return newtonMinimise(Eigen::VectorXd::Zero(x.cols()), loss, derivatives, 50, 1e-9);
}

std::vector<CodewordFactors> learnCodewordFactors(const std::vector<CalibrationSample>& samples, size_t categories,
                                                  int codewords, const DiscriminativeWeightParams& params) {
  if (codewords <= 0) throw Error(ErrorCode::kInvalidInput, "learnCodewordFactors: no codewords");
  std::vector<CodewordFactors> out(categories);
  for (size_t c = 0; c < categories; ++c) {
    std::vector<const CalibrationSample*> own;
    for (const auto& s : samples) {
      if (s.category == static_cast<int>(c)) own.push_back(&s);
    }
    const auto positives = std::count_if(own.begin(), own.end(), [](const CalibrationSample* s) { return s->positive; });
    if (positives < 5 || static_cast<size_t>(positives) == own.size()) continue;
    CodewordFactors& result = out[c];
    Eigen::MatrixXd x;
    Eigen::VectorXd y;
    design(own, codewords, x, y);
    std::vector<int> folds;
    for (const auto* s : own) folds.push_back(s->fold);
    result.held_out_loss = std::numeric_limits<double>::infinity();
    for (const double ridge : params.ridges) {
      const double loss = heldOutLoss(x, y, folds, kInputs + codewords, ridgeOf(codewords, ridge));
      if (loss < result.held_out_loss) {
        result.held_out_loss = loss;
        result.ridge = ridge;
      }
    }
    result.held_out_loss_without = heldOutLoss(x, y, folds, kInputs, ridgeOf(codewords, 0));
    const Eigen::VectorXd w = ridgeLogistic(x, y, ridgeOf(codewords, result.ridge));
    result.score_slope = w[1];
    if (!(result.score_slope > 0)) continue;  // a score that does not raise the odds says nothing of votes
    result.factors.resize(static_cast<size_t>(codewords));
    for (int k = 0; k < codewords; ++k) {
      const double lowered = std::min(w[kInputs + k] / result.score_slope, 0.0);
      result.factors[static_cast<size_t>(k)] = static_cast<float>(std::max(std::exp(lowered), params.lowest));
    }
    double sum = 0;
    int counted = 0;
    for (const auto* s : own) {
      if (!s->positive || s->codewords.empty()) continue;
      double mean = 0;
      for (const int k : s->codewords) {
        if (k >= 0 && k < codewords) mean += result.factors[static_cast<size_t>(k)];
      }
      sum += mean / static_cast<double>(s->codewords.size());
      ++counted;
    }
    result.true_peaks_mean = counted > 0 ? sum / counted : 1.0;
  }
  return out;
}

std::string describeFactors(const std::string& category, const CodewordFactors& factors) {
  std::ostringstream line;
  line << category << " codeword weights learned: ";
  if (factors.factors.empty()) {
    line << "none";
    return line.str();
  }
  std::vector<float> sorted = factors.factors;
  std::sort(sorted.begin(), sorted.end());
  const auto lowered = std::count_if(sorted.begin(), sorted.end(), [](float f) { return f < 0.99f; });
  line << "ridge " << factors.ridge << ", held-out log-loss " << factors.held_out_loss << " against "
       << factors.held_out_loss_without << " without the codewords; " << lowered << " of " << sorted.size()
       << " codewords lowered, median factor " << sorted[sorted.size() / 2] << ", the true peaks' mean "
       << factors.true_peaks_mean;
  return line.str();
}

void applyCodewordFactors(Model& model, const std::vector<CodewordFactors>& factors) {
  for (size_t c = 0; c < model.categories.size() && c < factors.size(); ++c) {
    const CodewordFactors& f = factors[c];
    if (f.factors.empty()) continue;
    auto& weights = model.categories[c].global_votes.codeword_weights;
    if (weights.empty()) weights.assign(f.factors.size(), 1.0f);
    if (weights.size() != f.factors.size()) {
      throw Error(ErrorCode::kInvalidInput, "applyCodewordFactors: " + std::to_string(f.factors.size()) + " factors for " +
                                                std::to_string(weights.size()) + " codeword weights of category '" +
                                                model.categories[c].name + "'");
    }
    for (size_t k = 0; k < weights.size(); ++k) weights[k] = std::clamp(weights[k] * f.factors[k], 1e-6f, 1.0f);
    for (auto& [key, threshold] : model.categories[c].thresholds) {
      if (key.codebook == CodebookType::kGlobal) threshold *= static_cast<float>(f.true_peaks_mean);
    }
  }
}

}  // namespace ism
