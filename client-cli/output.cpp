#include "output.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace hdeform::cli {

const std::vector<MeasureColumn>& measure_columns() {
  static const std::vector<MeasureColumn> cols = {
      {"E", "E", [](const pb::Measures& m) { return m.e(); }, false},
      {"E_iso^N", "E_iso_N", [](const pb::Measures& m) { return m.e_iso_n(); }, false},
      {"E_conf^N", "E_conf_N", [](const pb::Measures& m) { return m.e_conf_n(); }, false},
      {"E_area %", "E_area_pct", [](const pb::Measures& m) { return m.e_area_pct(); }, false},
      {"max e_iso", "max_e_iso", [](const pb::Measures& m) { return m.max_e_iso(); }, false},
      {"max e_conf", "max_e_conf", [](const pb::Measures& m) { return m.max_e_conf(); }, false},
      {"max e_f^2", "max_ef2", [](const pb::Measures& m) { return m.max_ef2(); }, false},
      {"flips", "flips", [](const pb::Measures& m) { return double(m.flips()); }, true},
  };
  return cols;
}

std::string g17(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string shortest(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string g6(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

void print_measures(std::ostream& out, const pb::Measures& m) {
  std::size_t w = 0;
  for (const auto& c : measure_columns()) w = std::max(w, std::string(c.label).size());
  for (const auto& c : measure_columns()) {
    std::string label = c.label;
    label.resize(w, ' ');
    const double v = c.get(m);
    out << label << "  " << (c.integer ? std::to_string(static_cast<long long>(v)) : g6(v))
        << "\n";
  }
}

std::string sweep_csv_header() {
  std::string h = "beta";
  for (const auto& c : measure_columns()) h += std::string(",") + c.csv;
  return h;
}

std::string sweep_csv(const std::vector<SweepPoint>& rows) {
  std::string s = sweep_csv_header() + "\n";
  for (const auto& r : rows) {
    s += shortest(r.beta);
    for (const auto& c : measure_columns()) {
      const double v = c.get(r.measures);
      s += ",";
      s += c.integer ? std::to_string(static_cast<long long>(v)) : g17(v);
    }
    s += "\n";
  }
  return s;
}

void print_table(std::ostream& out, const std::vector<std::vector<std::string>>& rows,
                 std::size_t left_columns) {
  if (rows.empty()) return;
  std::vector<std::size_t> w(rows[0].size(), 0);
  for (const auto& r : rows)
    for (std::size_t i = 0; i < r.size() && i < w.size(); ++i) w[i] = std::max(w[i], r[i].size());
  for (const auto& r : rows) {
    std::string line;
    for (std::size_t i = 0; i < r.size() && i < w.size(); ++i) {
      if (i) line += "  ";
      const std::string pad(w[i] - r[i].size(), ' ');
      // text columns left-aligned; numbers right-aligned, lining up on their last digit
      line += i < left_columns ? r[i] + pad : pad + r[i];
    }
    while (!line.empty() && line.back() == ' ') line.pop_back();
    out << line << "\n";
  }
}

void print_sweep_table(std::ostream& out, const std::vector<SweepPoint>& rows) {
  std::vector<std::vector<std::string>> t;
  std::vector<std::string> header{"beta"};
  for (const auto& c : measure_columns()) header.emplace_back(c.label);
  t.push_back(header);
  for (const auto& r : rows) {
    std::vector<std::string> row{shortest(r.beta)};
    for (const auto& c : measure_columns()) {
      const double v = c.get(r.measures);
      row.push_back(c.integer ? std::to_string(static_cast<long long>(v)) : g6(v));
    }
    t.push_back(row);
  }
  print_table(out, t);
}

// ---------------------------------------------------------------------------------------
// SVG

namespace {

double nice_number(double x, bool round) {
  if (!(x > 0)) return 1;
  const double e = std::floor(std::log10(x));
  const double f = x / std::pow(10.0, e);
  double nf;
  if (round)
    nf = f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10;
  else
    nf = f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10;
  return nf * std::pow(10.0, e);
}

struct Axis {
  double lo, hi, step;
};

Axis nice_axis(double lo, double hi, int ticks = 5) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) lo = 0, hi = 1;
  if (hi < lo) std::swap(lo, hi);
  if (hi - lo <= std::abs(hi) * 1e-12 || hi == lo) {
    const double pad = lo == 0 ? 1 : std::abs(lo) * 0.1;
    lo -= pad;
    hi += pad;
  }
  const double range = nice_number(hi - lo, false);
  const double step = nice_number(range / (ticks - 1), true);
  return {std::floor(lo / step) * step, std::ceil(hi / step) * step, step};
}

std::string tick_label(double v, double step) {
  if (std::abs(v) < step * 1e-9) v = 0;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

}  // namespace

std::string sweep_svg(const std::vector<SweepPoint>& rows, const std::string& title,
                      const std::string& beta_units) {
  const auto& cols = measure_columns();
  const int ncol = 4, nrow = static_cast<int>((cols.size() + ncol - 1) / ncol);
  const double pw = 280, ph = 210;                   // panel size
  const double ml = 62, mr = 22, mt = 28, mb = 40;   // plot margins inside a panel
  const double top = 44;                             // figure title
  const double W = ncol * pw, H = top + nrow * ph;

  std::vector<SweepPoint> pts = rows;
  std::sort(pts.begin(), pts.end(),
            [](const SweepPoint& a, const SweepPoint& b) { return a.beta < b.beta; });
  double bmin = 0, bmax = 1;
  if (!pts.empty()) bmin = pts.front().beta, bmax = pts.back().beta;
  const Axis xa = nice_axis(bmin, bmax);

  std::ostringstream s;
  s << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W << "\" height=\"" << H
    << "\" viewBox=\"0 0 " << W << " " << H << "\" font-family=\"sans-serif\" font-size=\"11\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    << "<text x=\"" << W / 2 << "\" y=\"26\" text-anchor=\"middle\" font-size=\"16\">"
    << esc(title) << "</text>\n";

  for (std::size_t ci = 0; ci < cols.size(); ++ci) {
    const auto& c = cols[ci];
    const double ox = static_cast<double>(ci % ncol) * pw;
    const double oy = top + static_cast<double>(ci / ncol) * ph;
    const double x0 = ox + ml, x1 = ox + pw - mr, y0 = oy + ph - mb, y1 = oy + mt;

    double vmin = INFINITY, vmax = -INFINITY;
    for (const auto& p : pts) {
      const double v = c.get(p.measures);
      if (std::isfinite(v)) vmin = std::min(vmin, v), vmax = std::max(vmax, v);
    }
    if (!(vmin <= vmax)) vmin = 0, vmax = 1;
    Axis ya = nice_axis(vmin, vmax);
    if (c.integer && ya.step < 1) ya = {std::floor(ya.lo), std::ceil(ya.hi), 1};
    if (vmin >= 0 && ya.lo < 0) ya.lo = 0;  // non-negative measures: no negative axis
    auto X = [&](double b) { return x0 + (b - xa.lo) / (xa.hi - xa.lo) * (x1 - x0); };
    auto Y = [&](double v) { return y0 - (v - ya.lo) / (ya.hi - ya.lo) * (y0 - y1); };

    s << "<g class=\"panel\" id=\"panel-" << c.csv << "\">\n"
      << "<text x=\"" << num((x0 + x1) / 2) << "\" y=\"" << num(oy + 18)
      << "\" text-anchor=\"middle\" font-size=\"13\" font-weight=\"bold\">" << esc(c.label)
      << "</text>\n";
    // grid and ticks
    const int nx = static_cast<int>(std::round((xa.hi - xa.lo) / xa.step));
    for (int i = 0; i <= nx; ++i) {
      const double b = xa.lo + i * xa.step, x = X(b);
      s << "<line x1=\"" << num(x) << "\" y1=\"" << num(y0) << "\" x2=\"" << num(x) << "\" y2=\""
        << num(y1) << "\" stroke=\"#e4e4e4\"/>\n"
        << "<line x1=\"" << num(x) << "\" y1=\"" << num(y0) << "\" x2=\"" << num(x) << "\" y2=\""
        << num(y0 + 4) << "\" stroke=\"black\"/>\n"
        << "<text x=\"" << num(x) << "\" y=\"" << num(y0 + 15) << "\" text-anchor=\"middle\">"
        << tick_label(b, xa.step) << "</text>\n";
    }
    const int ny = static_cast<int>(std::round((ya.hi - ya.lo) / ya.step));
    for (int i = 0; i <= ny; ++i) {
      const double v = ya.lo + i * ya.step, y = Y(v);
      s << "<line x1=\"" << num(x0) << "\" y1=\"" << num(y) << "\" x2=\"" << num(x1) << "\" y2=\""
        << num(y) << "\" stroke=\"#e4e4e4\"/>\n"
        << "<line x1=\"" << num(x0 - 4) << "\" y1=\"" << num(y) << "\" x2=\"" << num(x0)
        << "\" y2=\"" << num(y) << "\" stroke=\"black\"/>\n"
        << "<text x=\"" << num(x0 - 6) << "\" y=\"" << num(y + 4) << "\" text-anchor=\"end\">"
        << tick_label(v, ya.step) << "</text>\n";
    }
    // axes
    s << "<path d=\"M" << num(x0) << " " << num(y1) << " V" << num(y0) << " H" << num(x1)
      << "\" fill=\"none\" stroke=\"black\"/>\n"
      << "<text x=\"" << num((x0 + x1) / 2) << "\" y=\"" << num(y0 + 30)
      << "\" text-anchor=\"middle\">\u03b2 (" << esc(beta_units) << ")</text>\n";
    // data
    std::string poly;
    for (const auto& p : pts) {
      const double v = c.get(p.measures);
      if (!std::isfinite(v)) continue;
      poly += num(X(p.beta)) + "," + num(Y(v)) + " ";
    }
    if (!poly.empty()) {
      poly.pop_back();
      s << "<polyline points=\"" << poly << "\" fill=\"none\" stroke=\"#1f77b4\" "
        << "stroke-width=\"1.8\"/>\n";
    }
    for (const auto& p : pts) {
      const double v = c.get(p.measures);
      if (!std::isfinite(v)) continue;
      s << "<circle cx=\"" << num(X(p.beta)) << "\" cy=\"" << num(Y(v))
        << "\" r=\"2.8\" fill=\"#1f77b4\"><title>\u03b2=" << shortest(p.beta) << ": " << g6(v)
        << "</title></circle>\n";
    }
    s << "</g>\n";
  }
  s << "</svg>\n";
  return s.str();
}

}  // namespace hdeform::cli
