#include "session_report.h"

#include "output.h"

#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <ctime>
#include <numbers>
#include <sstream>

namespace hdeform::cli {

std::string utc_time(std::int64_t unix_ms) {
  if (unix_ms <= 0) return "-";
  const std::time_t t = static_cast<std::time_t>(unix_ms / 1000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

namespace {

// A handle transform in protobuf's JSON mapping ("{}" for the identity).
std::string transform_json(const pb::HandleTransform& t) {
  std::string out;
  google::protobuf::util::JsonPrintOptions o;
  o.preserve_proto_field_names = true;
  if (!google::protobuf::util::MessageToJsonString(t, &out, o).ok()) return "{}";
  return out;
}

void put_vec(std::ostream& out, const pb::Vec3& v) {
  out << g6(v.x()) << ' ' << g6(v.y()) << ' ' << g6(v.z());
}

// For people, as the command line takes it: "translate 0 0.05 0.02, rotate 25° about 1 0 0,
// scale 1, pivot centroid", 6 significant digits (--json has the exact numbers). A stream,
// not string concatenation: GCC 12 reports a false -Wrestrict on long + chains.
std::string transform_text(const pb::HandleTransform& t) {
  std::ostringstream s;
  if (t.matrix_size() == 16) {
    s << "matrix";
    for (double v : t.matrix()) s << ' ' << g6(v);
  } else {
    s << "translate ";
    put_vec(s, t.translation());
    const auto& q = t.rotation();
    const double n = std::sqrt(q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
    const double sin_half = std::sqrt(q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
    if (t.has_rotation() && n > 0 && sin_half > 1e-12 * n) {
      const double deg = 2 * std::atan2(sin_half, q.w()) * 180 / std::numbers::pi;
      s << ", rotate " << g6(deg) << "\u00b0 about " << g6(q.x() / sin_half) << ' '
        << g6(q.y() / sin_half) << ' ' << g6(q.z() / sin_half);
    } else {
      s << ", no rotation";
    }
    s << ", scale ";
    switch (t.scale_case()) {
      case pb::HandleTransform::kUniformScale: s << g6(t.uniform_scale()); break;
      case pb::HandleTransform::kAxisScale: put_vec(s, t.axis_scale()); break;
      case pb::HandleTransform::kStretch:
        s << "stretch";
        for (double v : t.stretch().m()) s << ' ' << g6(v);
        break;
      default: s << '1';
    }
  }
  s << ", pivot ";
  if (t.has_pivot())
    put_vec(s, t.pivot());
  else
    s << "centroid";
  return s.str();
}

const char* units_name(pb::BetaUnits u) { return u == pb::BETA_UNITS_RAW ? "raw" : "area"; }

// "0.1 (area)", "0.1 (raw, automatic) + 2 local"
std::string beta_text(const pb::Beta& b) {
  std::string s = shortest(b.value()) + " (" + units_name(b.units());
  if (b.automatic()) s += ", automatic";
  s += ")";
  if (b.local_size() > 0) s += " + " + std::to_string(b.local_size()) + " local";
  return s;
}

}  // namespace

std::vector<std::vector<std::string>> session_table(const std::vector<pb::Session>& sessions) {
  std::vector<std::vector<std::string>> t{
      {"name", "mesh", "vertices", "version", "observers", "updated"}};
  for (const auto& s : sessions)
    t.push_back({s.name(), s.mesh_name().empty() ? "-" : s.mesh_name(),
                 std::to_string(s.vertex_count()), std::to_string(s.version()),
                 std::to_string(s.observers()), utc_time(s.update_time_unix_ms())});
  return t;
}

void print_session(std::ostream& out, const pb::Session& s) {
  out << "name:        " << s.name() << "\n"
      << "mesh:        " << (s.mesh_name().empty() ? "-" : s.mesh_name()) << " (hash "
      << s.mesh_hash() << ")\n"
      << "size:        " << s.vertex_count() << " vertices, " << s.triangle_count()
      << " triangles\n"
      << "version:     " << s.version() << " (config " << s.config_version() << ")\n";
  if (s.constrained())
    out << "constraints: " << s.constraints().fixed().ids_size() << " fixed, "
        << s.constraints().handles_size() << " handle(s)\n";
  else
    out << "constraints: none\n";
  out << "beta:        " << beta_text(s.beta()) << "\n";
  for (int i = 0; i < s.transforms_size(); ++i) {
    out << "handle " << i << ":    " << transform_text(s.transforms(i)) << "\n";
  }
  out << "observers:   " << s.observers() << "\n"
      << "created:     " << utc_time(s.create_time_unix_ms()) << "\n"
      << "updated:     " << utc_time(s.update_time_unix_ms()) << "\n";
}

nlohmann::json session_json(const pb::Session& s) {
  nlohmann::json local = nlohmann::json::array();
  for (const auto& l : s.beta().local())
    local.push_back({{"beta", l.beta()}, {"falloff_radius", l.falloff_radius()}});
  nlohmann::json transforms = nlohmann::json::array();
  for (const auto& t : s.transforms())
    transforms.push_back(nlohmann::json::parse(transform_json(t)));
  return {
      {"name", s.name()},
      {"mesh", s.mesh_name()},
      {"mesh_hash", s.mesh_hash()},
      {"vertices", s.vertex_count()},
      {"triangles", s.triangle_count()},
      {"version", s.version()},
      {"config_version", s.config_version()},
      {"constrained", s.constrained()},
      {"fixed", s.constraints().fixed().ids_size()},
      {"handles", s.constraints().handles_size()},
      {"beta",
       {{"value", s.beta().value()},
        {"units", units_name(s.beta().units())},
        {"automatic", s.beta().automatic()},
        {"local", local}}},
      {"transforms", transforms},
      {"observers", s.observers()},
      {"created", utc_time(s.create_time_unix_ms())},
      {"updated", utc_time(s.update_time_unix_ms())},
  };
}

}  // namespace hdeform::cli
