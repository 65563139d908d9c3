#include "core/recognition/top_seen.h"

namespace ism {

TopSeenCheck checkTopSeen(const VerificationScene& scene, const Hypothesis& hypothesis, const TopSeenParams& params) {
  TopSeenCheck check;
  if (!params.enabled || scene.map || !hypothesis.verification) return check;
  check.looked = true;
  check.seen = hypothesis.verification->top_seen;
  check.consistent = hypothesis.verification->top_consistent;
  check.min_seen = params.min_seen;
  check.min_share = params.min_share;
  return check;
}

}  // namespace ism
