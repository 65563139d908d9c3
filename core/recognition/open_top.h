#pragma once
// An open top: nothing stands over a chair or a couch. People sit on them and lean on their
// backrests, so the space just above a seat's top is free, while voting also puts chairs and couches
// into and under taller furniture, where the scene goes on above the box. Each verified, upright
// hypothesis of a category that is not flat-topped (things stand on tables) counts the measured
// points over the inner part of its footprint: those from 0.1 to 0.6 m above its top against those
// in its body, from 0.1 m above the floor to its top. It is dropped when the share above exceeds
// max_share: the scene says the object is part of something taller, or stands under something
// (support relations as in Silberman, Hoiem, Kohli and Fergus, "Indoor segmentation and support
// inference from RGBD images", ECCV 2012: furniture stands on the floor, not inside other
// furniture). On the dev clouds every share from 0.05 to 0.2 gained alike and 0.3-0.5 less
// (docs/EVALUATION.md); the laxest of the plateau is kept.
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct OpenTopParams {
  bool enabled = true;
  float inner = 0.8f;            // the share of the footprint's sides looked over (walls behind a couch stay out)
  float from = 0.1f, to = 0.6f;  // above the top (m)
  float body_from = 0.1f;        // the body from this above the floor (m) to the top
  float max_share = 0.2f;        // of the points above among those above and in the body
};

struct OpenTopCheck {
  bool looked = false;  // verified, upright and enabled
  int above = 0, body = 0;
  float max_share = 0;  // OpenTopParams::max_share
  float share() const { return above + body > 0 ? static_cast<float>(above) / static_cast<float>(above + body) : 0.0f; }
  bool covered() const { return looked && share() > max_share; }
};

OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params = {});

}  // namespace ism
