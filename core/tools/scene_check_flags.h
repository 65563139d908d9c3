#pragma once
// The command-line switches that turn the default preset's scene checks off (scene_checks.h), in
// one table that ism-detect and both of ism-eval's subcommands register: each check is named,
// described and switched off in one place, so the tools cannot drift apart. The help of the other
// default-preset switch they share, --bin-peaks, is here for the same reason.
#include <CLI/CLI.hpp>
#include <array>
#include <cstddef>

#include "core/recognition/scene_checks.h"

namespace ism::cli {

// --bin-peaks, registered by ism-detect and both of ism-eval's subcommands.
inline constexpr const char* kBinPeaksHelp =
    "default preset: centre each peak on its own bin's votes, as the seed, not on its bin's and its 26 "
    "neighbours' (hough_space.h)";

struct SceneCheckSwitch {
  const char* flag;
  const char* help;
  void (*off)(SceneCheckParams&);
};

inline constexpr std::array<SceneCheckSwitch, 19> kSceneCheckSwitches{{
    {"--no-top-height",
     "keep tables whose measured top is more than 0.1 m lower or higher than every training table's (top_extent.h)",
     [](SceneCheckParams& p) { p.top_extent.height_slack = 0; }},
    {"--no-seat-under-top",
     "keep a couch of which a table's box covers a third of the footprint, and the less confident table too "
     "(seat_under_top.h)",
     [](SceneCheckParams& p) { p.seat_under_top.enabled = false; }},
    {"--no-open-top",
     "keep chairs and couches with measured surface standing over their top, or none in the top of their body "
     "(open_top.h)",
     [](SceneCheckParams& p) { p.open_top.enabled = false; }},
    {"--no-upper-part",
     "keep chairs and couches with no measured surface in the top of their body, where a backrest is (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.min_upper = 0; }},
    {"--no-upper-clearance",
     "count the points in the top of a chair's or couch's body next to surface standing over its top too, as a "
     "wall's at its edge (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.upper_clearance = 0; }},
    {"--no-level-top",
     "keep couches over whose footprint the measured surface is one level, or beside which it runs on at a seat's "
     "height, as a bed's mattress does (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.max_level = 0; }},
    {"--no-level-run-on",
     "keep couches beside which the measured surface runs on level above a seat's height, up to a tall bed's "
     "mattress at 0.8 m, when none runs on at a seat's height (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.run_level_to = 0; }},
    {"--no-behind-back",
     "keep chairs behind whose fitted back the measured surface runs on level, as a bed's mattress behind the bench "
     "at its foot (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.behind_back = false; }},
    {"--no-near-side",
     "keep chairs and couches of a single view with measured surface standing over the side of their footprint "
     "that faces the sensor, as a wall between the sensor and them (open_top.h)",
     [](SceneCheckParams& p) { p.open_top.near_edge = 0; }},
    {"--no-seen-top",
     "keep chairs and couches of a single view through whose fitted shape's top part, a backrest, the sensor sees "
     "nearly everywhere (top_seen.h)",
     [](SceneCheckParams& p) { p.top_seen.enabled = false; }},
    {"--no-bare-floor", "keep hypotheses with bare floor in the middle of their footprint (bare_floor.h)",
     [](SceneCheckParams& p) { p.bare_floor.enabled = false; }},
    {"--no-under-top",
     "keep tables under whose measured top nothing is measured, as under a bed's or a cabinet's (under_top.h)",
     [](SceneCheckParams& p) { p.under_top.enabled = false; }},
    {"--no-closed-front",
     "count a single view's measured points under a table's top along the side facing the sensor, where a "
     "dresser's front stands, as the open space under a table (under_top.h)",
     [](SceneCheckParams& p) { p.under_top.near_edge = 0; }},
    {"--no-seat-area",
     "keep chairs and couches with little measured at seat height over their footprint, as over a desk's legs "
     "(seat_area.h)",
     [](SceneCheckParams& p) { p.seat_area.enabled = false; }},
    {"--no-seat-run",
     "keep chairs and couches whose measured surface at seat height runs less than half as far as their "
     "category's shortest training shape's (seat_run.h)",
     [](SceneCheckParams& p) { p.seat_run.enabled = false; }},
    {"--keep-topless",
     "keep tables whose top the scene does not show, with their fitted shapes' boxes (top_extent.h)",
     [](SceneCheckParams& p) { p.top_extent.require_top = false; }},
    {"--no-top-extent",
     "tables' boxes stay their fitted shapes' instead of spanning the scene's table top (top_extent.h)",
     [](SceneCheckParams& p) { p.top_extent.enabled = false; }},
    {"--no-footprint-prior",
     "keep tables whose measured top is deeper or shallower than every training table's of given size "
     "(top_extent.h)",
     [](SceneCheckParams& p) { p.top_extent.footprint_prior = false; }},
    {"--no-hidden-top",
     "a table's box spans only the top measured in one piece, not across the swaths something in front hides from "
     "the sensor (top_extent.h)",
     [](SceneCheckParams& p) { p.top_extent.max_hidden_run = 0; }},
}};

// Which switches were given. add() may register them on several (sub)commands; apply() switches the
// given checks off in `params`.
class SceneCheckFlags {
 public:
  void add(CLI::App& app) {
    for (size_t i = 0; i < kSceneCheckSwitches.size(); ++i) {
      app.add_flag(kSceneCheckSwitches[i].flag, given_[i],
                   std::string("default preset: ") + kSceneCheckSwitches[i].help);
    }
  }
  void apply(SceneCheckParams& params) const {
    for (size_t i = 0; i < kSceneCheckSwitches.size(); ++i) {
      if (given_[i]) kSceneCheckSwitches[i].off(params);
    }
  }

 private:
  std::array<bool, kSceneCheckSwitches.size()> given_{};
};

}  // namespace ism::cli
