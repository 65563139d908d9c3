#pragma once
// A table's box from the scene's own table top. Tables and desks come in every length, and a
// training shape's box covers only as much as that shape: with it a 2.4 m desk is two 1.2 m
// tables, and a 5.6 m dining table one 1.1 m table at its near end, neither overlapping the real
// top by a quarter. A category whose training shapes are flat-topped (most of their
// surface at their top: tables, desks) has its verified hypotheses' boxes taken from the
// horizontal surface at the fitted top's height that the scene measured there, as tabletop
// segmentation finds supporting planes in the gravity frame (Rusu, Marton, Blodow, Beetz et al.,
// "Close-range scene segmentation and reconstruction of 3D point cloud maps for mobile
// manipulation in domestic environments", IROS 2009): the layer of measured points at that
// height, closed over the holes of a sparse sample, opened to drop what is thin there (a chair's
// backrest pushed to the table, a wall), grown from the fitted footprint, and boxed by the
// tighter of the fitted heading and the layer's own main axis. Where something in front of the top
// hides a swath of it from the sensor, the top continues past the swath: the cells the sensor cannot
// see are unknown, not empty, as an occupancy map's (Hornung, Wurm, Bennewitz, Stachniss and Burgard,
// "OctoMap", Autonomous Robots 2013). Two hypotheses on one long top then share its box and merge in
// suppression.h.
#include "core/model/model.h"
#include "core/recognition/hypothesis.h"
#include "core/recognition/verification.h"

namespace ism {

struct TopExtentParams {
  bool enabled = true;
  // A training shape is flat-topped when at least this share of its surface points lie within
  // `layer` of its top (a table's top holds most of its surface; a chair's or a couch's top, the
  // rim of a backrest, little); a category is when most of its shapes are.
  float min_top_share = 0.3f;
  float layer = 0.03f;        // half the thickness of the layer at the top's height (m)
  float cell = 0.05f;         // the layer's grid (m)
  // The top is sought at the densest 2 cm of measured points over the fitted footprint, from
  // this far below the fitted top to this far above it (m), where at least min_points lie.
  float below = 0.2f, above = 0.1f;
  int min_points = 10;
  float max_side = 6.0f;      // the top is grown within a square of this side about the fitted box (m)
  // The top is grown across cells of its height that something measured between them and the
  // sensor hides (a chair's back drawn up to the table, seen past it), as far as this (m) from
  // measured top to measured top; what it reaches is boxed by its measured points only. Not in
  // maps, whose made-up viewpoint sees nothing. 0: only across measured cells.
  float max_hidden_run = 0.8f;
  // A top whose narrow side is outside the training shapes' narrow sides, give or take the priors'
  // slack, is dropped (withinFootprintPrior).
  bool footprint_prior = true;
  // A top measured more than this below the lowest training table's top or above the highest one's
  // (objects whose size was given) is dropped (m; 0: every height kept). Tables and desks are built
  // to a few standard heights (the shipped training tables span 0.72-0.78 m), unlike their lengths;
  // a level surface well below them is a low table's, an armchair's arms or a bed's, one above them
  // a counter's or a cabinet's. The slack is a Hough bin, for the floor's estimate and the 2 cm
  // layers the top is found in.
  float height_slack = 0.1f;
  // A verified hypothesis of a flat-topped category whose top the scene does not show (no layer of
  // at least min_points measured points near the fitted top over its footprint) is dropped: a
  // table is its top. false keeps it with its fitted shape's box (ism-eval --keep-topless).
  bool require_top = true;
};

// Whether most of `category`'s training shapes are flat-topped (TopExtentParams::min_top_share).
bool flatTopped(const CategoryModel& category, const TopExtentParams& params = {});

// What extendToTop found: it did not look (the hypothesis is not verified and upright, or the step
// is off), it looked and the scene shows no top there, or it found the top and boxed it.
enum class TopFound { kNotLooked, kMissing, kFound };

// Replaces a verified, upright hypothesis' box by the extent of the scene's top surface there, from
// the floor (or the box's bottom) to the top's height. Leaves it as it is where no top is found,
// or where it does not look.
TopFound extendToTop(const VerificationScene& scene, Hypothesis& hypothesis, const TopExtentParams& params = {});

// The footprint prior of a flat-topped category: whether the narrow side of the hypothesis' upright
// box (in the frame of `to_gravity`) lies within the narrow sides of the category's training
// objects whose size was given (TrainingObject::size_guessed; none: no prior), give or take `slack`
// (m). The narrow side only: a table's depth is bounded by the reach across it, and the beds that
// voting takes for tables are deeper than any table, while desks and dining tables come in any
// length.
bool withinFootprintPrior(const Hypothesis& hypothesis, const CategoryModel& category, const Eigen::Matrix3f& to_gravity,
                          float slack);

// The height prior of a flat-topped category: whether the height of the hypothesis' upright box (in
// the frame of `to_gravity`; extendToTop runs it from the floor to the measured top) lies within
// the heights of the category's training objects whose size was given, give or take `slack` (m).
// No such objects: no prior.
bool withinHeightPrior(const Hypothesis& hypothesis, const CategoryModel& category, const Eigen::Matrix3f& to_gravity,
                       float slack);

}  // namespace ism
