#pragma once
// A seat under a table's top: two pieces of furniture do not stand in one place. A chair is
// pushed under a table, its seat below the top, but a couch is not: it is longer than a table is
// deep and its back runs its whole length. Voting puts couches along a table's side, where the
// chairs pushed up to it give a row of seats and backrests; the table's box, the top the scene
// measured there (top_extent.h), then covers much of the couch's footprint. Of a verified answer
// of a long-seated category (a couch: its training shapes' shortest run at seat height, seat_run.h,
// is longer than one person's seat) and one of a flat-topped category whose box covers at least
// max_covered of the seat's footprint, the less confident is dropped, as a holistic scene parse
// rejects boxes that intersect (Lin, Fidler and Urtasun, "Holistic scene understanding for 3D
// object detection with RGBD cameras", ICCV 2013; Huang et al., "Holistic 3D scene parsing and
// reconstruction from a single RGB image", ECCV 2018, penalise physically violating boxes).
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/seat_run.h"
#include "core/recognition/top_extent.h"

namespace ism {

struct SeatUnderTopParams {
  bool enabled = true;
  // A category is long-seated when its training shapes' shortest seat run is at least this (m):
  // the shipped couches' is 1.67 m, chairs' 0.4-0.5 m.
  float long_seat = 1.0f;
  // The share of a long seat's footprint under a table's box from which the two do not both stand
  // there. A couch along a dev scan's dining table had 0.40-0.53 of it under the top, a true couch
  // beside a low table 0.11 (docs/EVALUATION.md, "A couch under a table's top").
  float max_covered = 1.0f / 3;
};

enum class FloorKind { kOther, kTop, kLongSeat };

// What `category` is to this check: flat-topped (top_extent.h), long-seated, or neither. Without
// training shapes, neither.
FloorKind floorKind(const CategoryModel& category, const TopExtentParams& top, const SeatRunParams& seat,
                    const SeatUnderTopParams& params = {});

// Of each verified, upright hypothesis of a long seat and each of a top in `hypotheses` (their
// kinds given by `kind` of the category's name) whose box covers at least max_covered of the seat's
// footprint (in the gravity frame of `to_gravity`), the less confident is moved to `dropped`, with
// passed_selection false. Taken most confident first: a dropped or refuted hypothesis drops
// nothing. The others keep their order.
void dropSeatsUnderTops(std::vector<Hypothesis>& hypotheses, const std::function<FloorKind(const std::string&)>& kind,
                        const Eigen::Matrix3f& to_gravity, const SeatUnderTopParams& params,
                        std::vector<Hypothesis>& dropped);

}  // namespace ism
