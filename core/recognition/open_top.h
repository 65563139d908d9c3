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
// The top of the body must be there: a chair's backrest, a couch's back and arms rise above the seat.
// Voting also puts chairs on coffee tables, low cabinets and the floor's clutter, whose surface ends
// at seat height: a hypothesis with no measured point over its footprint in a band above every seat
// and below every backrest's top is dropped, where each of its category's training shapes has
// surface in that band (a category a user trains on ottomans has none, and keeps its hypotheses).
// Nor is the top of the body one level: a couch's seat covers part of its footprint, and its back
// and arms rise over the rest. Voting also puts couches on the ends of beds, whose mattress runs
// level over the whole footprint at about a seat's height and gives the top of the body its points.
// Where most of the footprint's cells hold their highest measured point within one band, for a
// category each of whose training shapes is less level than that, the hypothesis is refuted
// (Hypothesis::refuted): an object of its size stands there, but not one of its category. So is a
// couch on the foot of a bed seen end on, whose footboard or end gives it a back: the mattress runs
// on past a side of its footprint at about a seat's height, filling a strip beside it, where a
// couch stands free, against a wall, or with a coffee table shorter than itself some way off. It keeps
// that object from the other categories' answers (a table on the same bed) and is then rejected:
// the object gets no answer rather than the next category's, as an open-set recogniser answers
// "unknown" when its best class is refuted (Scheirer et al., "Toward open set recognition",
// TPAMI 2013). A chair on a bench at a bed's foot has the mattress behind its back: a chair stands
// with a table before it, not behind it, so only the strip behind its fitted shape's back is looked
// at there, and only for a level surface (OpenTopCheck::behindBack). Over the side facing the
// sensor of a single view nothing may stand either (OpenTopCheck::hidden): there a wall puts the
// box behind it, out of the sensor's sight.
#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct OpenTopParams {
  bool enabled = true;
  float inner = 0.8f;            // the share of the footprint's sides looked over (walls behind a couch stay out)
  float from = 0.1f, to = 0.6f;  // above the top (m)
  float body_from = 0.1f;        // the body from this above the floor (m) to the top
  float max_share = 0.2f;        // of the points above among those above and in the body
  // The top of the body, from upper_from to upper_to above the floor (m), over the whole footprint:
  // a chair's backrest, a couch's back and arms, above every seat and below every back's top.
  // Fewer than min_upper measured points there, and the scene shows no such top (a coffee table, a
  // low cabinet): dropped.
  float upper_from = 0.55f, upper_to = 0.75f;
  int min_upper = 1;             // 0: not looked at
  // A wall or taller furniture at the footprint's edge fills that band with its own face. So the
  // footprint is cut into cells upper_cell square, and the band's points count only in cells
  // farther than upper_clearance (measured between cells) from every cell holding surface from
  // `from` to `to` above the top, what the open top counts as over it: a backrest or arm ends at
  // the top, a wall goes on. A couch's back against a wall keeps its arms' and cushions' fronts.
  // On the dev scans clearances of 0.1-0.3 m lost no true object, 0.4 m lost chairs on two pairs
  // (docs/EVALUATION.md, "A wall in the top of the body"). 0: every point in the band counts.
  float upper_cell = 0.1f, upper_clearance = 0.2f;
  // A level top: the footprint in cells level_cell square, each cell's highest measured point from
  // body_from above the floor to level_over above the top. When max_level or more of the cells hold
  // it within one band level_band high, the scene shows one level surface there. 0: not looked at.
  float level_cell = 0.08f, level_band = 0.1f, level_over = 0.3f;
  float max_level = 0.6f;
  // A surface running on past a side (only where the level top is looked at): the strip beside
  // each side of the footprint, from run_near to run_far out and along the middle `inner` of the
  // side, in cells run_cell square; a cell is filled by a measured point from run_from to run_to
  // above the floor. When max_run_on or more of one strip's cells are filled, a level surface at a
  // seat's height goes on there (a bed's mattress). On the dev scans 0.8 and 0.9 refuted alike, and
  // no true sofa (docs/EVALUATION.md, "A bed's mattress beside a couch"). 0: not looked at.
  float run_near = 0.05f, run_far = 0.55f, run_cell = 0.1f;
  float run_from = 0.35f, run_to = 0.7f;
  // A cell is also filled where its highest measured point below run_level_cap lies from run_from
  // to run_level_to, when max_run_on of the strip's cells hold theirs within one level_band: a
  // level surface up to a tall bed's mattress (0.74-0.77 m on SUN RGB-D's val_000004), while a
  // corner sofa's next seat and back, or a wall (its cells reach the cap), make no one level.
  // run_level_to <= run_from: not looked at (docs/EVALUATION.md, "A tall bed's mattress").
  float run_level_to = 0.8f, run_level_cap = 1.0f;
  float max_run_on = 0.8f;
  // A chair or a couch is also refuted when max_run_on of the cells of the strip behind its fitted
  // shape's back hold their highest point level, as above (a couch's strips on every side count
  // that already, with the level top). The seat's band is not counted there: chairs drawn up to
  // each other fill it. On the dev scans the level strips on every side lost chairs at tables,
  // whose tops stand at a mattress's height (docs/EVALUATION.md, "A tall bed's mattress beside a
  // couch").
  bool behind_back = true;
  // Nothing stands over the side of the footprint that faces the sensor either, and there the inner
  // part does not keep a wall out: a wall along that side stands between the sensor and the box,
  // which then lies behind it, where the sensor cannot have seen the object. Voting puts couches
  // there when a wall's face fits a couch's back (SUN RGB-D's train_005054, a kitchen's bare wall).
  // The strip from the side near_edge into the footprint, along the middle `inner` of the side,
  // counts its points above the top against those in its body, as the inner part does; over
  // max_share, the hypothesis is contradicted. Single views only: a map's viewpoint is made up
  // (viewpoint.h). On the dev scans strips of 0.1, 0.2 and 0.3 m lost no true object
  // (docs/EVALUATION.md, "A wall between the sensor and a couch"). 0: not looked at.
  float near_edge = 0.2f;
};

struct OpenTopCheck {
  bool looked = false;  // verified, upright and enabled
  int above = 0, body = 0;
  int near_above = 0, near_body = 0;  // the same, in the strip along the side facing the sensor
  int upper = 0;        // points in the top of the body
  float max_share = 0;  // OpenTopParams::max_share
  int min_upper = 0;    // OpenTopParams::min_upper
  float level_share = 0;  // the share of the footprint's cells whose highest point lies in one band
  float max_level = 0;    // OpenTopParams::max_level
  float run_on_share = 0;  // the most filled strip's share of filled cells
  float max_run_on = 0;    // OpenTopParams::max_run_on, 0 where the level top is not looked at
  float behind_back_share = 0;  // the strip behind the fitted shape's back: its share of level cells
  float max_behind = 0;         // OpenTopParams::max_run_on, 0 where it is not looked at
  float share() const { return above + body > 0 ? static_cast<float>(above) / static_cast<float>(above + body) : 0.0f; }
  bool covered() const { return looked && share() > max_share; }
  float nearShare() const {
    return near_above + near_body > 0 ? static_cast<float>(near_above) / static_cast<float>(near_above + near_body) : 0.0f;
  }
  // Something rises over the side facing the sensor: the box lies behind it.
  bool hidden() const { return looked && nearShare() > max_share; }
  bool topless() const { return looked && upper < min_upper; }
  // Something stands there, but not the category: the hypothesis is refuted (Hypothesis::refuted).
  bool level() const { return looked && max_level > 0 && level_share >= max_level; }
  // A level surface at a seat's height runs on past a side: refuted too.
  bool runsOn() const { return looked && max_run_on > 0 && run_on_share >= max_run_on; }
  // A level surface behind the back: refuted too.
  bool behindBack() const { return looked && max_behind > 0 && behind_back_share >= max_behind; }
  bool refuted() const { return level() || runsOn() || behindBack(); }
  bool contradicted() const { return covered() || topless() || hidden(); }
};

// `fitted`: the training shape verification fitted (Verification::object), whose back the strip
// behind the back is looked behind; null, not looked at.
OpenTopCheck checkOpenTop(const VerificationScene& scene, const Hypothesis& hypothesis, const OpenTopParams& params = {},
                          const TrainingObject* fitted = nullptr);

// Whether each of the category's training shapes (standing on z = 0) has at least params.min_upper
// points in the band of the top of the body; false without shapes or with min_upper 0.
bool upperPartTrained(const CategoryModel& category, const OpenTopParams& params = {});

// The share of a footprint's cells whose highest point lies within one band of params.level_band:
// `points` are (x, y, height above the floor) about the footprint's centre, along its sides, of a
// footprint `width` x `depth`, each cell level_cell square; points outside it, below
// params.body_from or above `top` + params.level_over are not looked at.
float levelShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, float top,
                 const OpenTopParams& params = {});

// The share of filled cells in the most filled of the four strips beside a footprint `width` x
// `depth` (OpenTopParams::run_near ... max_run_on), filled by a point at a seat's height or by the
// cells' level highest points, whichever fills more: `points` are (x, y, height above the floor)
// about the footprint's centre, along its sides.
float runOnShare(const std::vector<Eigen::Vector3f>& points, float width, float depth, const OpenTopParams& params = {});

// The side of a box (0, 1: past +x, -x of its width; 2, 3: past +y, -y of its depth) that the
// back of `object` faces, turned by `yaw` about up relative to the box: the side nearest the
// direction from its axis to its surface in the top quarter of its height (a chair's backrest).
// -1 when that surface lies on the axis.
int backSide(const TrainingObject& object, float yaw);

// Whether each of the category's training shapes is less level than params.max_level (couches,
// whose back and arms rise over the seat; not chairs, whose seat covers most of the footprint);
// false without shapes or with max_level 0.
bool stepTopTrained(const CategoryModel& category, const OpenTopParams& params = {});

}  // namespace ism
