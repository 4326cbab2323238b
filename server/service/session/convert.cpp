#include "service/session/convert.h"

#include "service/infra/service_error.h"

#include "engine/io/selection.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace hdeform::service {

Eigen::Vector3d from_proto(const pb::Vec3& v) { return {v.x(), v.y(), v.z()}; }

void to_proto(const Eigen::Vector3d& v, pb::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

HandleTransform from_proto(const pb::HandleTransform& t, const Eigen::Vector3d& default_pivot) {
  HandleTransform h;
  if (t.has_pivot()) h.pivot = from_proto(t.pivot());
  if (t.matrix_size() > 0) {
    if (t.matrix_size() != 16)
      throw InvalidInput("transform matrix needs 16 numbers (4×4 row-major), got " +
                         std::to_string(t.matrix_size()));
    Eigen::Matrix4d T;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) T(r, c) = t.matrix(4 * r + c);
    const Eigen::Vector3d pivot = h.pivot ? *h.pivot : default_pivot;
    h = HandleTransform::from_matrix(T, pivot);
    h.validate();
    return h;
  }
  const auto& q = t.rotation();
  if (!(q.w() == 0 && q.x() == 0 && q.y() == 0 && q.z() == 0))
    h.rotation = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());
  switch (t.scale_case()) {
    case pb::HandleTransform::kUniformScale:
      h.stretch = t.uniform_scale() * Eigen::Matrix3d::Identity();
      break;
    case pb::HandleTransform::kAxisScale:
      h.stretch = from_proto(t.axis_scale()).asDiagonal();
      break;
    case pb::HandleTransform::kStretch: {
      if (t.stretch().m_size() != 9)
        throw InvalidInput("transform stretch needs 9 numbers (3×3 row-major), got " +
                           std::to_string(t.stretch().m_size()));
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) h.stretch(r, c) = t.stretch().m(3 * r + c);
      break;
    }
    case pb::HandleTransform::SCALE_NOT_SET:
      break;
  }
  if (t.has_translation()) h.translation = from_proto(t.translation());
  h.validate();
  return h;
}

void to_proto(const HandleTransform& t, pb::HandleTransform* out) {
  out->Clear();
  if (t.pivot) to_proto(*t.pivot, out->mutable_pivot());
  auto* q = out->mutable_rotation();
  q->set_w(t.rotation.w());
  q->set_x(t.rotation.x());
  q->set_y(t.rotation.y());
  q->set_z(t.rotation.z());
  if (t.stretch != Eigen::Matrix3d::Identity()) {
    auto* m = out->mutable_stretch();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m->add_m(t.stretch(r, c));
  }
  to_proto(t.translation, out->mutable_translation());
}

std::vector<HandleTransform> from_proto(
    const google::protobuf::RepeatedPtrField<pb::HandleTransform>& ts, const ConstraintSet& cs) {
  if (ts.size() != cs.num_handles())
    throw InvalidInput("expected " + std::to_string(cs.num_handles()) +
                       " handle transform(s), one per handle, got " + std::to_string(ts.size()));
  std::vector<HandleTransform> out;
  out.reserve(ts.size());
  for (int j = 0; j < ts.size(); ++j) {
    try {
      out.push_back(from_proto(ts.Get(j), cs.centroid(j)));
    } catch (const InvalidInput& e) {
      throw InvalidInput("handle " + std::to_string(j) + ": " + e.what());
    }
  }
  return out;
}

Beta beta_from(double value, pb::BetaUnits units) {
  if (!std::isfinite(value) || value < 0 || value >= 1)
    throw InvalidInput("beta must satisfy 0 <= beta < 1, got " + std::to_string(value));
  Beta b;
  b.value = value;
  b.units = units_from(units);
  return b;
}

BetaUnits units_from(pb::BetaUnits units) {
  return units == pb::BETA_UNITS_RAW ? BetaUnits::raw : BetaUnits::area;
}

double convert_beta(const PreparedMesh& mesh, double value, BetaUnits from, BetaUnits to) {
  if (from == to || value == 0.0) return value;
  if (to == BetaUnits::raw) return mesh.raw_beta({value, BetaUnits::area});
  // raw → area: β/(1−β) = s · β′/(1−β′), s = 1/√(total area).
  const double ratio = value / ((1.0 - value) * std::sqrt(mesh.total_area()));
  return ratio / (1.0 + ratio);
}

Beta from_proto(const pb::Beta& b) { return beta_from(b.value(), b.units()); }

void to_proto(const Beta& b, pb::Beta* out) {
  out->set_value(b.value);
  out->set_units(b.units == BetaUnits::raw ? pb::BETA_UNITS_RAW : pb::BETA_UNITS_AREA);
}

void to_proto(const Measures& m, pb::Measures* out) {
  out->set_e(m.E);
  out->set_e_iso_n(m.E_iso_N);
  out->set_e_conf_n(m.E_conf_N);
  out->set_e_area_pct(m.E_area_pct);
  out->set_max_e_iso(m.max_e_iso);
  out->set_max_e_conf(m.max_e_conf);
  out->set_max_ef2(m.max_ef2);
  out->set_flips(m.flips);
}

void check_limit(std::size_t count, std::size_t limit, const std::string& what,
                 const char* flag) {
  if (count > limit)
    throw ServiceError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                       what + ": " + std::to_string(count) + " exceeds the limit of " +
                           std::to_string(limit) + " (" + flag + ")");
}

std::vector<int> resolve_region(const pb::Region& region, const Vertices& V,
                                const std::string& what, std::span<const int> base_to_engine,
                                const RequestLimits& limits) {
  const int n = static_cast<int>(V.rows());
  const int base_n = base_to_engine.empty() ? n : static_cast<int>(base_to_engine.size());
  check_limit(static_cast<std::size_t>(region.selectors_size()), limits.max_selectors,
              what + " selectors", "--max-selectors");
  std::vector<int> ids;
  std::string empty_selectors;  // for the message when the whole region is empty
  for (int s = 0; s < region.selectors_size(); ++s) {
    const auto& sel = region.selectors(s);
    const std::string where = what + " selector " + std::to_string(s);
    if (sel.kind_case() == pb::Selector::kIds)
      check_limit(static_cast<std::size_t>(sel.ids().ids_size()), limits.max_selector_ids,
                  where + " ids", "--max-selector-ids");
    if (sel.kind_case() == pb::Selector::kBaseIds)
      check_limit(static_cast<std::size_t>(sel.base_ids().ids_size()), limits.max_selector_ids,
                  where + " base_ids", "--max-selector-ids");
    std::vector<int> part;
    switch (sel.kind_case()) {
      case pb::Selector::kIds:
        for (int id : sel.ids().ids()) {
          if (id < 0 || id >= n)
            throw InvalidInput(where + ": vertex id " + std::to_string(id) +
                               " out of range [0, " + std::to_string(n) + ")");
          part.push_back(id);
        }
        std::sort(part.begin(), part.end());
        part.erase(std::unique(part.begin(), part.end()), part.end());
        break;
      case pb::Selector::kBaseIds:
        for (int id : sel.base_ids().ids()) {
          if (id < 0 || id >= base_n)
            throw InvalidInput(where + ": base vertex id " + std::to_string(id) +
                               " out of range [0, " + std::to_string(base_n) +
                               ") (base GLB vertices)");
          part.push_back(base_to_engine.empty() ? id : base_to_engine[id]);
        }
        std::sort(part.begin(), part.end());
        part.erase(std::unique(part.begin(), part.end()), part.end());
        break;
      case pb::Selector::kBox:
        part = select_box(V, from_proto(sel.box().min()), from_proto(sel.box().max()));
        break;
      case pb::Selector::kSphere:
        if (!(sel.sphere().radius() >= 0) || !std::isfinite(sel.sphere().radius()))
          throw InvalidInput(where + ": sphere radius must be finite and >= 0");
        part = select_sphere(V, from_proto(sel.sphere().center()), sel.sphere().radius());
        break;
      case pb::Selector::kHalfSpace: {
        const Eigen::Vector3d normal = from_proto(sel.half_space().normal());
        if (!(normal.norm() > 0) || !normal.allFinite())
          throw InvalidInput(where + ": half-space normal must be finite and non-zero");
        part = select_half_space(V, normal, sel.half_space().offset());
        break;
      }
      case pb::Selector::kSel: {
        const auto labels = parse_sel(sel.sel().content(), n, where + " (.sel)");
        part = select_label(labels, sel.sel().label());
        break;
      }
      case pb::Selector::KIND_NOT_SET:
        throw InvalidInput(where + ": selector has no kind (ids, box, sphere, half_space, sel)");
    }
    if (part.empty()) empty_selectors += (empty_selectors.empty() ? "" : ", ") + std::to_string(s);
    ids = unite(std::move(ids), part);
  }
  if (ids.empty() && region.selectors_size() > 0)
    throw InvalidInput(what + " selects no vertices (empty selector" +
                       (region.selectors_size() > 1 ? "s " : " ") + empty_selectors + ")");
  return ids;
}

Constraints resolve_constraints(const pb::Constraints& c, const Vertices& V,
                                std::span<const int> base_to_engine,
                                const RequestLimits& limits) {
  check_limit(static_cast<std::size_t>(c.handles_size()), limits.max_handles, "handles",
              "--max-handles");
  Constraints out;
  out.fixed = resolve_region(c.fixed(), V, "the fixed region", base_to_engine, limits);
  out.handles.reserve(c.handles_size());
  for (int j = 0; j < c.handles_size(); ++j)
    out.handles.push_back(
        resolve_region(c.handles(j), V, "handle " + std::to_string(j), base_to_engine, limits));
  return out;
}

void to_proto(const Constraints& c, pb::ResolvedConstraints* out) {
  out->Clear();
  out->mutable_fixed()->mutable_ids()->Add(c.fixed.begin(), c.fixed.end());
  for (const auto& h : c.handles) {
    auto* ids = out->add_handles()->mutable_ids();
    ids->Add(h.begin(), h.end());
  }
}

}  // namespace hdeform::service
