#include "text_parsers.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

namespace hdeform::cli {

namespace {

std::string g6(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r\n");
  return s.substr(b, e - b + 1);
}

std::string resolve_path(const std::string& path, const std::string& base_dir) {
  if (base_dir.empty() || path.empty() || std::filesystem::path(path).is_absolute()) return path;
  return (std::filesystem::path(base_dir) / path).lexically_normal().string();
}

double to_double(const std::string& token, const std::string& where) {
  const std::string t = trim(token);
  if (t.empty()) throw CliError(where + ": empty number");
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (end != t.c_str() + t.size()) throw CliError(where + ": '" + t + "' is not a number");
  // ERANGE on underflow gives a denormal or 0: fine. On overflow: HUGE_VAL.
  if (!std::isfinite(v) || (errno == ERANGE && std::abs(v) == HUGE_VAL))
    throw CliError(where + ": '" + t + "' is not a finite number");
  return v;
}

std::vector<double> parse_numbers(const std::string& text, const std::string& where,
                                  std::size_t count) {
  std::vector<double> out;
  std::string token;
  std::istringstream ss(text);
  while (std::getline(ss, token, ',')) out.push_back(to_double(token, where));
  if (!text.empty() && text.back() == ',') throw CliError(where + ": trailing ','");
  if (count > 0 && out.size() != count)
    throw CliError(where + ": expected " + std::to_string(count) +
                   " comma-separated numbers, got " + std::to_string(out.size()) + " in '" +
                   text + "'");
  return out;
}

SelectorSpec parse_selector_spec(const std::string& raw, const std::string& where) {
  const std::string text = trim(raw);
  const auto colon = text.find(':');
  if (colon == std::string::npos)
    throw CliError(where + ": selector '" + text +
                   "' needs a kind: ids:, box:, sphere:, half: or sel:");
  SelectorSpec s;
  s.kind = text.substr(0, colon);
  const std::string args = text.substr(colon + 1);
  const std::string w = where + " '" + text + "'";
  if (s.kind == "ids") {
    s.numbers = parse_numbers(args, w);
    for (double v : s.numbers)
      if (v != std::floor(v) || v < 0 || v > 2147483647.0)
        throw CliError(w + ": vertex id " + g6(v) + " is not a non-negative integer");
    if (s.numbers.empty()) throw CliError(w + ": no vertex ids");
  } else if (s.kind == "box") {
    s.numbers = parse_numbers(args, w, 6);
  } else if (s.kind == "sphere") {
    s.numbers = parse_numbers(args, w, 4);
  } else if (s.kind == "half") {
    s.numbers = parse_numbers(args, w, 4);
  } else if (s.kind == "sel") {
    const auto last = args.rfind(':');
    if (last == std::string::npos || last == 0) throw CliError(w + ": expected sel:FILE:LABEL");
    s.file = args.substr(0, last);
    const double label = to_double(args.substr(last + 1), w);
    if (label != std::floor(label) || label < 0 || label > 2)
      throw CliError(w + ": label must be 0, 1 or 2");
    s.label = static_cast<int>(label);
  } else {
    throw CliError(where + ": unknown selector kind '" + s.kind +
                   "' (ids, box, sphere, half or sel)");
  }
  return s;
}

std::vector<SelectorSpec> parse_selectors_spec(const std::string& text, const std::string& where) {
  std::vector<SelectorSpec> out;
  std::string part;
  std::istringstream ss(text);
  while (std::getline(ss, part, '|')) {
    if (trim(part).empty()) continue;
    out.push_back(parse_selector_spec(part, where));
  }
  if (out.empty()) throw CliError(where + ": empty selector");
  return out;
}

void check_local_beta(double beta, double radius, const std::string& where) {
  if (!(beta >= 0 && beta < 1)) throw CliError(where + ": beta " + g6(beta) + " is outside [0, 1)");
  if (!(radius >= 0) || !std::isfinite(radius)) throw CliError(where + ": radius must be >= 0");
}

LocalBetaSpec parse_local_beta_spec(const std::string& raw, const std::string& where) {
  const std::string text = trim(raw);
  const std::string w = where + " '" + text + "'";
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t at; (at = text.find('@', start)) != std::string::npos; start = at + 1)
    parts.push_back(text.substr(start, at - start));
  parts.push_back(text.substr(start));
  if (parts.size() < 2) throw CliError(w + ": expected SEL@BETA or SEL@BETA@RADIUS");
  auto is_number = [](const std::string& s) {
    const std::string t = trim(s);
    char* end = nullptr;
    std::strtod(t.c_str(), &end);
    return !t.empty() && end == t.c_str() + t.size();
  };
  // From the right: BETA[@RADIUS] are numbers; everything before is the selector text.
  const std::size_t numbers =
      parts.size() >= 3 && is_number(parts.back()) && is_number(parts[parts.size() - 2]) ? 2 : 1;
  LocalBetaSpec e;
  for (std::size_t i = 0; i + numbers < parts.size(); ++i)
    e.selectors += (i ? "@" : "") + parts[i];
  e.beta = parse_numbers(parts[parts.size() - numbers], w + ": BETA", 1)[0];
  e.radius = numbers == 2 ? parse_numbers(parts.back(), w + ": RADIUS", 1)[0] : 0.0;
  if (trim(e.selectors).empty()) throw CliError(w + ": no selector before '@'");
  parse_selectors_spec(e.selectors, where);  // syntax
  check_local_beta(e.beta, e.radius, w);
  return e;
}

TransformValues parse_transform_values(const TransformText& t, const std::string& where) {
  TransformValues out;
  if (!t.def_file.empty()) {
    if (!t.rotate.empty() || !t.translate.empty() || !t.scale.empty())
      throw CliError(where + ": a .def matrix excludes rotate/translate/scale");
    out.def_file = t.def_file;
  }
  if (!t.rotate.empty()) {
    const std::string w = where + " rotate";
    const std::string r = trim(t.rotate);
    const auto comma = r.find(',');
    const std::string first = comma == std::string::npos ? r : trim(r.substr(0, comma));
    double ax = 0, ay = 0, az = 0, deg = 0;
    if (first == "x" || first == "y" || first == "z" || first == "X" || first == "Y" ||
        first == "Z") {
      if (comma == std::string::npos) throw CliError(w + ": expected AXIS,DEG");
      deg = parse_numbers(r.substr(comma + 1), w, 1)[0];
      (first == "x" || first == "X" ? ax : first == "y" || first == "Y" ? ay : az) = 1;
    } else {
      const auto v = parse_numbers(r, w, 4);
      ax = v[0], ay = v[1], az = v[2], deg = v[3];
    }
    const double n = std::hypot(ax, ay, az);  // no overflow for huge finite components
    if (n == 0) throw CliError(w + ": the rotation axis is zero");
    if (!std::isfinite(n)) throw CliError(w + ": the rotation axis is too long");
    const double half = std::fmod(deg, 720.0) * M_PI / 360.0;
    out.rotation = {std::cos(half), std::sin(half) * ax / n, std::sin(half) * ay / n,
                    std::sin(half) * az / n};
  }
  if (!t.translate.empty()) {
    const auto v = parse_numbers(t.translate, where + " translate", 3);
    out.translate = {v[0], v[1], v[2]};
  }
  if (!t.scale.empty()) {
    out.scale = parse_numbers(t.scale, where + " scale");
    if (out.scale.size() != 1 && out.scale.size() != 3)
      throw CliError(where + " scale: expected S or SX,SY,SZ");
  }
  if (!t.pivot.empty()) {
    const auto v = parse_numbers(t.pivot, where + " pivot", 3);
    out.pivot = {v[0], v[1], v[2]};
  }
  return out;
}

}  // namespace hdeform::cli
