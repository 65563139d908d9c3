#include "core/recognition/seat_under_top.h"

#include <algorithm>

#include "core/common/upright_box.h"

namespace ism {

FloorKind floorKind(const CategoryModel& category, const TopExtentParams& top, const SeatRunParams& seat,
                    const SeatUnderTopParams& params) {
  if (flatTopped(category, top)) return FloorKind::kTop;
  const std::optional<float> run = trainingSeatRun(category, seat);
  return run && *run >= params.long_seat ? FloorKind::kLongSeat : FloorKind::kOther;
}

void dropSeatsUnderTops(std::vector<Hypothesis>& hypotheses, const std::function<FloorKind(const std::string&)>& kind,
                        const Eigen::Matrix3f& to_gravity, const SeatUnderTopParams& params,
                        std::vector<Hypothesis>& dropped) {
  if (!params.enabled) return;
  struct Candidate {
    size_t index;
    FloorKind kind;
    UprightBox box;
  };
  std::vector<Candidate> candidates;
  bool tops = false, seats = false;
  for (size_t i = 0; i < hypotheses.size(); ++i) {
    const Hypothesis& h = hypotheses[i];
    if (!h.verification || !h.upright_box) continue;
    const FloorKind k = kind(h.category);
    if (k == FloorKind::kOther) continue;
    (k == FloorKind::kTop ? tops : seats) = true;
    candidates.push_back({i, k, uprightBoxOf(h.box, to_gravity)});
  }
  if (!tops || !seats) return;
  std::stable_sort(candidates.begin(), candidates.end(), [&](const Candidate& a, const Candidate& b) {
    return hypotheses[a.index].confidence > hypotheses[b.index].confidence;
  });
  std::vector<bool> drop(hypotheses.size(), false);
  std::vector<const Candidate*> standing;  // more confident, kept and not refuted
  for (const auto& c : candidates) {
    const bool under = std::any_of(standing.begin(), standing.end(), [&](const Candidate* s) {
      if (s->kind == c.kind) return false;
      const UprightBox& seat = c.kind == FloorKind::kLongSeat ? c.box : s->box;
      const float seat_area = seat.size.x() * seat.size.y();
      return seat_area > 0 && footprintOverlap(c.box, s->box) >= params.max_covered * seat_area;
    });
    if (under) {
      drop[c.index] = true;
    } else if (!hypotheses[c.index].refuted) {
      standing.push_back(&c);
    }
  }
  std::vector<Hypothesis> kept;
  for (size_t i = 0; i < hypotheses.size(); ++i) {
    if (drop[i]) {
      hypotheses[i].passed_selection = false;
      dropped.push_back(std::move(hypotheses[i]));
    } else {
      kept.push_back(std::move(hypotheses[i]));
    }
  }
  hypotheses = std::move(kept);
}

}  // namespace ism
