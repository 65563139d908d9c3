#pragma once
// A backrest the sensor sees through. A chair's top part is its backrest; voting also puts chairs
// on benches, beds' ends and low cabinets, whose surface ends at seat height. There verification
// can still fit a chair's shape fairly well (the seat and legs agree), while from the sensor the
// fitted backrest stands in front of the surface behind it: the sensor measured farther along
// nearly every ray through it, so nothing solid is there (the free-space term of Aldoma et al.,
// "A global hypotheses verification method for 3D object recognition", ECCV 2012, read over the
// backrest alone rather than over the whole shape, whose seat can outweigh it). A chair or couch
// of a single view whose fitted shape's top part (VerificationParams::top_part) has at least
// min_seen pixels the sensor saw, and under min_share of them explained, is dropped. Maps are not
// looked at: their sparse samples leave real backrests' points unmatched as often as not (on the
// dev ScanNet rooms true and false chairs' top parts were 0-100 % explained alike), and their
// viewpoint is made up. On the dev scans shares of 0.05 and 0.1 lost no true chair, 0.2 one
// (docs/EVALUATION.md, "A backrest seen through").
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct TopSeenParams {
  bool enabled = true;
  int min_seen = 20;        // the top part's pixels with a measurement not in front of it
  float min_share = 0.05f;  // of them, explained by the measured depth
};

struct TopSeenCheck {
  bool looked = false;  // verified, a single view, enabled
  int seen = 0, consistent = 0;
  int min_seen = 0;
  float min_share = 0;
  float share() const { return seen > 0 ? static_cast<float>(consistent) / static_cast<float>(seen) : 1.0f; }
  bool seenThrough() const { return looked && seen >= min_seen && share() < min_share; }
};

TopSeenCheck checkTopSeen(const VerificationScene& scene, const Hypothesis& hypothesis, const TopSeenParams& params = {});

}  // namespace ism
