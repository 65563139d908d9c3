#pragma once
// A seat's area: a chair or a couch is something to sit on, so over most of its footprint the
// sensor measures its seat (and the backrest's and arms' lower parts) at seat height. Voting
// also puts chairs and couches on a desk's legs and drawers, on a bed's end, on a cabinet's
// plinth: a line of parts at seat height (which passes the seat's run, seat_run.h) with nothing
// between them. A verified hypothesis of a category that is not flat-topped (tables have their
// top, top_extent.h) is dropped when fewer than min_share of the cells of its inner footprint
// that the sensor could see at seat height hold a measured point between `from` and `to` above
// the floor, provided every training shape of its category shows at least that share (a
// category of stools on three legs is not looked at). In a map every cell counts; in a single
// view a cell whose seat height lies behind measured surface (a couch seen from behind, its seat
// hidden by its back) or where nothing was measured says nothing, and a hypothesis with too few
// cells seen is kept. Another check of what the scene must show of an object's support surface,
// as the table's top and the space under it (Silberman, Hoiem, Kohli and Fergus, "Indoor
// segmentation and support inference from RGBD images", ECCV 2012).
#include <vector>

#include <Eigen/Core>

#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct SeatAreaParams {
  bool enabled = true;
  float inner = 0.8f;  // the share of the footprint's sides looked at (a neighbour's edge stays out)
  float cell = 0.1f;   // cells of the inner footprint (m)
  // Seat height (m above the floor): chairs' and couches' seats are 0.3-0.55 m high; a table's or
  // a desk's top (0.7 m and up) and the floor's clutter stay out.
  float from = 0.25f, to = 0.65f;
  float min_share = 0.3f;  // of the seen cells holding a point there: below it, dropped
  // A single view: a cell is seen where the sensor measured surface at its middle's seat height or
  // beyond it, up to `margin` (m) nearer; directions are binned `angle` (rad) wide. With fewer
  // than min_seen of the cells seen, nothing is decided.
  float margin = 0.1f;
  float angle = 0.02f;
  float min_seen = 0.3f;
};

struct SeatAreaCheck {
  bool looked = false;  // verified, upright, enabled, its category's shapes all show a seat, seen enough
  float share = 0;      // of the seen cells of the inner footprint holding a measured point at seat height
  float seen = 0;       // of the inner footprint's cells, the share the sensor could see at seat height
  float min_share = 0;  // SeatAreaParams::min_share
  bool bare() const { return looked && share < min_share; }
};

// The share of the inner footprint's cells holding a point between params.from and params.to:
// `points` (x, y about the footprint's centre along its sides, z above the floor) of a footprint
// `width` x `depth`, every cell seen.
float seatAreaShare(const std::vector<Eigen::Vector3f>& points, float width, float depth,
                    const SeatAreaParams& params = {});

// Whether the category has training shapes and each shows at least min_share (each in its own
// box, standing on z = 0): only then is the check asked of its hypotheses.
bool seatAreaTrained(const CategoryModel& category, const SeatAreaParams& params = {});

// `trained`: seatAreaTrained of the hypothesis' category, worked out once.
SeatAreaCheck checkSeatArea(const VerificationScene& scene, const Hypothesis& hypothesis, bool trained,
                            const SeatAreaParams& params = {});

}  // namespace ism
