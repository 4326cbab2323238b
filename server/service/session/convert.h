// proto ↔ engine conversions. Everything that can be wrong in a request throws
// hdeform::InvalidInput with a message naming the field (→ INVALID_ARGUMENT).
#pragma once

#include "engine/deform/deformer.h"
#include "hdeform/v1/deform.pb.h"
#include "service/infra/request_limits.h"

#include <google/protobuf/repeated_field.h>

#include <span>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

Eigen::Vector3d from_proto(const pb::Vec3& v);
void to_proto(const Eigen::Vector3d& v, pb::Vec3* out);

// One proto transform → engine. `default_pivot` (the handle's rest centroid) is used for
// the 4×4 matrix form when no pivot is given. Validates the result.
HandleTransform from_proto(const pb::HandleTransform& t, const Eigen::Vector3d& default_pivot);
// Canonical proto form (pivot if set, quaternion, stretch as Mat3 unless identity,
// translation). Round-trips bit for bit through from_proto.
void to_proto(const HandleTransform& t, pb::HandleTransform* out);

// Exactly one transform per handle of `cs`.
std::vector<HandleTransform> from_proto(
    const google::protobuf::RepeatedPtrField<pb::HandleTransform>& ts, const ConstraintSet& cs);

// Throws InvalidInput unless 0 ≤ value < 1 and finite.
Beta from_proto(const pb::Beta& b);
void to_proto(const Beta& b, pb::Beta* out);
Beta beta_from(double value, pb::BetaUnits units);
BetaUnits units_from(pb::BetaUnits units);
// The same β in other units (SPEC decision Units: β′/(1−β′) = β/((1−β)·s)); exact for 0.
double convert_beta(const PreparedMesh& mesh, double value, BetaUnits from, BetaUnits to);

void to_proto(const Measures& m, pb::Measures* out);

// Selectors → sorted unique vertex ids on the rest mesh (engine order). `base_ids`
// selectors map through `base_to_engine` (base-GLB vertex → engine vertex; empty: the
// identity on V's rows, as for OBJ/OFF/PLY/STL).
// A region that selects no vertex is an error naming the region and its empty selectors.
// Counts beyond `limits` throw RESOURCE_EXHAUSTED.
std::vector<int> resolve_region(const pb::Region& region, const Vertices& V,
                                const std::string& what,
                                std::span<const int> base_to_engine = {},
                                const RequestLimits& limits = {});
Constraints resolve_constraints(const pb::Constraints& c, const Vertices& V,
                                std::span<const int> base_to_engine = {},
                                const RequestLimits& limits = {});
void to_proto(const Constraints& c, pb::ResolvedConstraints* out);

}  // namespace hdeform::service
