#pragma once
// Codeword weights learned from the calibration rooms' peaks. The background's weights
// (background.h) say how often a codeword fires on what no category is; they cannot say which
// codewords make up the peaks that stand where no object of the category is. The rendered rooms'
// peaks can: each is labelled true or false by the room's furniture, and its supporting keypoints
// each activate one codeword. A logistic regression of the label on the peak's calibration inputs
// (ln s, ln(s / support), the fit, the profile distance) and on the share of its supporting
// keypoints that activate each codeword learns, per codeword, how much its presence in a peak
// raises or lowers the odds that the peak is true. Maji and Malik ("Object detection using a
// max-margin Hough transform", CVPR 2009) learn a Hough detector's codeword weights the same way,
// from its true and false peaks.
//
// A codeword whose slope lowers the odds by beta votes with its weight times exp(beta / a), a the
// slope of ln s: a peak whose every supporting keypoint activates it then scores as much lower as
// the regression says its odds are. No codeword gains votes: letting the weights rise as well put
// a few codewords above all others and ranked the real scans worse (docs/EVALUATION.md,
// "Codeword weights learned from the calibration rooms' peaks").
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "core/model/model.h"
#include "core/training/calibration.h"

namespace ism {

// DiscriminativeWeightParams: trainer.h, beside the calibration's.

// One category's learned factors, and what the report says of them.
struct CodewordFactors {
  std::vector<float> factors;  // per codeword, in [lowest, 1]; empty: the category keeps its weights
  double ridge = 0;            // the ridge chosen
  double score_slope = 0;      // a, the slope of ln s
  double held_out_loss = 0;    // the folds' summed log-loss at that ridge
  double held_out_loss_without = 0;  // and without the codewords
  double true_peaks_mean = 1;  // the mean factor over the true peaks' supporting keypoints
};

// Per category 0 .. categories - 1 of `samples` (`codewords` the global codebook's size), the
// factors; a category whose samples lack 5 positives or any negative gets none. Samples need their
// supporting keypoints' codewords (CalibrationSample::codewords).
std::vector<CodewordFactors> learnCodewordFactors(const std::vector<CalibrationSample>& samples, size_t categories,
                                                  int codewords, const DiscriminativeWeightParams& params);

// Multiplies each category's global codeword weights by its factors, and its global codebook's
// thresholds by its true peaks' mean factor: the lowest score that calibration and recognition
// look at (CalibrationParams::lowest_score_fraction of the threshold) moves with the scores.
void applyCodewordFactors(Model& model, const std::vector<CodewordFactors>& factors);

// The report's line: the ridge, the held-out log-loss with and without the codewords, and how far
// the factors fall.
std::string describeFactors(const std::string& category, const CodewordFactors& factors);

// Logistic regression by Newton's method on rows of `x` with labels `y` in {0, 1}, minimising the
// summed log-loss plus 0.5 * sum_j ridge_j w_j^2; each step halved until the loss falls.
Eigen::VectorXd ridgeLogistic(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& ridge);

}  // namespace ism
