#include "service/session/timeline.h"

#include "service/session/convert.h"

#include <algorithm>
#include <string>

namespace hdeform::service {

std::optional<Beta> ParsedTimeline::beta_at(double t) const {
  std::optional<Beta> out;
  for (std::size_t i = 0; i < keys.size() && keys[i].time <= t; ++i)
    if (betas[i]) out = betas[i];
  return out;
}

namespace {

Easing easing_from(pb::Easing e, const std::string& where) {
  switch (e) {
    case pb::EASING_LINEAR: return Easing::linear;
    case pb::EASING_SMOOTHSTEP: return Easing::smoothstep;
    default: throw InvalidInput(where + "easing: unknown value " + std::to_string(e));
  }
}

}  // namespace

ParsedTimeline parse_timeline(const pb::Timeline& timeline, const ConstraintSet& cs) {
  const std::string op = "SetTimeline ";
  ParsedTimeline out;
  out.easing = easing_from(timeline.easing(), op);
  if (static_cast<std::size_t>(timeline.keys_size()) > kMaxKeyframes)
    throw InvalidInput(op + "timeline: " + std::to_string(timeline.keys_size()) +
                       " keys exceed the limit of " + std::to_string(kMaxKeyframes));
  for (int j = 0; j < cs.num_handles(); ++j) out.rest_pivots.push_back(cs.centroid(j));
  std::vector<double> distinct;
  for (int i = 0; i < timeline.keys_size(); ++i) {
    const pb::Keyframe& k = timeline.keys(i);
    const std::string where = op + "keys[" + std::to_string(i) + "]";
    Keyframe key;
    key.time = k.time_s();
    if (k.has_easing()) key.easing = easing_from(k.easing(), where + ".");
    if (k.transforms_size() != cs.num_handles())
      throw InvalidInput(where + ": " + std::to_string(k.transforms_size()) +
                         " transforms for " + std::to_string(cs.num_handles()) + " handles");
    for (int j = 0; j < k.transforms_size(); ++j) {
      try {
        key.transforms.push_back(
            from_proto(k.transforms(j), out.rest_pivots[static_cast<std::size_t>(j)]));
      } catch (const InvalidInput& e) {
        throw InvalidInput(where + ".transforms[" + std::to_string(j) + "]: " + e.what());
      }
    }
    std::optional<Beta> beta;
    if (k.has_beta()) {
      if (k.beta().automatic() || k.beta().local_size() > 0)
        throw InvalidInput(where + ".beta: a key's β is a uniform value (not automatic, no "
                                   "local entries)");
      try {
        beta = from_proto(k.beta());
      } catch (const InvalidInput& e) {
        throw InvalidInput(where + ".beta: " + e.what());
      }
      // Compared in raw units: the same β given in two units is one factorization.
      const double raw = convert_beta(cs.mesh(), beta->value, beta->units, BetaUnits::raw);
      if (std::find(distinct.begin(), distinct.end(), raw) == distinct.end()) {
        distinct.push_back(raw);
        if (distinct.size() > kMaxTimelineBetas)
          throw InvalidInput(where + ".beta: more than " + std::to_string(kMaxTimelineBetas) +
                             " distinct β values in one timeline (each is a factorization)");
      }
    }
    out.keys.push_back(std::move(key));
    out.betas.push_back(beta);
  }
  try {
    check_keyframes(out.keys, cs.num_handles());
  } catch (const InvalidInput& e) {
    throw InvalidInput(op + e.what());
  }
  return out;
}

}  // namespace hdeform::service
