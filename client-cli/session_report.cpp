#include "session_report.h"

#include "output.h"

#include <google/protobuf/util/json_util.h>

#include <ctime>

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
    out << "handle " << i << ":    " << transform_json(s.transforms(i)) << "\n";
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
