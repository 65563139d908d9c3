#pragma once
// The box of a peak, standing upright: every vote that lands in the peak's cube was cast by one
// training object, whose size and heading in the vote frame the model keeps. Their weighted
// mean size is the box's size and their weighted mean heading its yaw (mod 180 degrees: a box
// turned half round is the same box), so a long table gets a long box and a chair a chair's,
// turned as the object is. With the floor known the box stands on it.
#include "core/common/types.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/voting.h"

namespace ism {

// Whether `caster`'s votes carry training objects and headings (upright models since they did).
bool hasUprightVotes(const VoteCaster& caster);

// Sets peak.box (and peak.upright_box) from the votes of peak.support_indices that land within
// `half_edge` of peak.center. Needs the features' gravity (Features::gravity) and
// hasUprightVotes(caster); otherwise the peak keeps its box.
void estimateUprightBox(const VoteCaster& caster, float half_edge, Hypothesis& peak);

}  // namespace ism
