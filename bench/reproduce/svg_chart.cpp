#include "svg_chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace hdeform::report {

namespace {
std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}
}  // namespace

void write_measures_chart(const std::string& path, const std::string& title,
                          const std::vector<Series>& series) {
  static const char* names[] = {"E", "E_iso^N", "E_conf^N", "E_area %", "max e_iso",
                                "max e_conf", "max e_f²"};
  static const char* colours[] = {"#c0392b", "#2c3e50", "#27ae60", "#8e44ad"};
  const int pw = 220, ph = 160, cols = 4, left = 50, top = 40;
  const int width = cols * (pw + left) + 20, height = 2 * (ph + 60) + top + 30;
  std::ofstream svg(path);
  if (!svg) throw std::runtime_error("cannot write " + path);
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
      << "' font-family='sans-serif' font-size='11'>\n<rect width='100%' height='100%' fill='white'/>\n"
      << "<text x='10' y='20' font-size='14'>" << title << ": measures against β</text>\n";
  for (int c = 0; c < 7; ++c) {
    const int x0 = left + (c % cols) * (pw + left), y0 = top + (c / cols) * (ph + 60);
    double lo = std::numeric_limits<double>::infinity(), hi = -lo, bmax = 0;
    for (const Series& s : series)
      for (const auto& [b, v] : s.points) {
        lo = std::min(lo, v[c]);
        hi = std::max(hi, v[c]);
        bmax = std::max(bmax, b);
      }
    if (!(hi > lo)) hi = lo + 1e-12 + std::abs(lo) * 0.01;
    bmax = std::max(bmax, 1e-9);
    auto X = [&](double b) { return x0 + pw * b / bmax; };
    auto Y = [&](double v) { return y0 + ph - ph * (v - lo) / (hi - lo); };
    svg << "<text x='" << x0 << "' y='" << y0 - 8 << "'>" << names[c] << "</text>\n"
        << "<rect x='" << x0 << "' y='" << y0 << "' width='" << pw << "' height='" << ph
        << "' fill='none' stroke='#999'/>\n";
    for (int t = 0; t <= 4; ++t) {
      const double v = lo + (hi - lo) * t / 4, b = bmax * t / 4;
      svg << "<text x='" << x0 - 4 << "' y='" << Y(v) + 4 << "' text-anchor='end'>" << fmt(v)
          << "</text>\n<text x='" << X(b) << "' y='" << y0 + ph + 14
          << "' text-anchor='middle'>" << fmt(b) << "</text>\n";
    }
    svg << "<text x='" << x0 + pw / 2 << "' y='" << y0 + ph + 28 << "' text-anchor='middle'>β</text>\n";
    for (std::size_t k = 0; k < series.size(); ++k) {
      svg << "<polyline fill='none' stroke='" << colours[k % 4] << "' stroke-width='1.5'"
          << (k ? " stroke-dasharray='4 3'" : "") << " points='";
      for (const auto& [b, v] : series[k].points) svg << X(b) << "," << Y(v[c]) << " ";
      svg << "'/>\n";
      for (const auto& [b, v] : series[k].points)
        svg << "<circle cx='" << X(b) << "' cy='" << Y(v[c]) << "' r='2.5' fill='"
            << colours[k % 4] << "'/>\n";
    }
  }
  // Legend in the eighth cell.
  const int lx = left + 3 * (pw + left), ly = top + ph + 60 + 20;
  for (std::size_t k = 0; k < series.size(); ++k)
    svg << "<line x1='" << lx << "' y1='" << ly + 18 * k << "' x2='" << lx + 30 << "' y2='"
        << ly + 18 * k << "' stroke='" << colours[k % 4] << "' stroke-width='2'"
        << (k ? " stroke-dasharray='4 3'" : "") << "/>\n<text x='" << lx + 36 << "' y='"
        << ly + 18 * k + 4 << "'>" << series[k].name << "</text>\n";
  svg << "</svg>\n";
}

}  // namespace hdeform::report
