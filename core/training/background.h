#pragma once
// Background: what no category is. Rooms are full of cabinets, shelves, beds and boxes whose
// corners and edges look locally like a chair's or a table's, and every one of their keypoints
// casts the votes of the codewords it activates. Scans of such meshes (manifest rows of the
// category "background") teach the codebook what is not furniture: each category's codeword
// gets the weight p(category | codeword) against background, with equal priors,
//   w = r_cat / (r_cat + r_bg),  r = the share of that side's keypoints activating the codeword,
// so a codeword that background activates as often as the category halves its votes and one
// that fires mostly on background hardly votes (the discriminative codeword weights of
// Knopp, Prasad and Van Gool, "Orientation invariant 3D object classification using Hough
// transform based methods", 3DOR 2010, and of Gall and Lempitsky's class-specific Hough forests,
// CVPR 2009, which learn object against background patches).
#include <string>
#include <vector>

#include "core/codebook/codebook.h"
#include "core/training/trainer.h"

namespace ism {

// The manifest category whose meshes are background, not a category of the model.
inline const std::string kBackgroundCategory = "background";

// Per codeword of `codebook`, how many keypoints of `scans` activate it under `activation`.
std::vector<int> activationCounts(const Codebook& codebook, const std::vector<const TrainingScan*>& scans,
                                  const ActivationParams& activation);

// Per codeword, r_cat / (r_cat + r_bg) from the two sides' activation counts (each side's share
// of its total); 1 where background never activates it, and for every codeword when either side
// is empty. Throws Error(kInvalidInput) when the counts' lengths differ.
std::vector<float> codewordWeights(const std::vector<int>& category_counts, const std::vector<int>& background_counts);

}  // namespace ism
