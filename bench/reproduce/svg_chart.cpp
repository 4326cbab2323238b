#include "svg_chart.h"

#include "write_if_changed.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace hdeform::report {

namespace {

// Ticks at round numbers (1, 2 or 5 × 10^k) covering [lo, hi]: about `n` intervals.
struct Ticks {
  double lo, hi, step;
  int decimals;  // enough to tell the ticks apart, no more
  int count() const { return static_cast<int>(std::lround((hi - lo) / step)); }
  double at(int i) const { return lo + i * step; }  // no accumulated rounding
};

Ticks nice_ticks(double lo, double hi, int n = 4) {
  if (!(hi > lo)) {
    const double pad = lo == 0 ? 1 : std::abs(lo) * 0.05;
    lo -= pad;
    hi += pad;
  }
  const double raw = (hi - lo) / n;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double f = raw / mag;
  const double step = (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * mag;
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step) + 1e-9)));
  return {std::floor(lo / step + 1e-9) * step, std::ceil(hi / step - 1e-9) * step, step,
          decimals};
}

// A tick label: fixed-point with the ticks' decimals ("0.25", "183"), or "1.5e+06" for
// numbers too long for the margin.
std::string label(double v, const Ticks& t) {
  if (std::abs(v) < t.step * 1e-9) v = 0;
  char b[48];
  if (t.decimals <= 6 && std::abs(v) < 1e7)
    std::snprintf(b, sizeof b, "%.*f", t.decimals, v);
  else
    std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

// Width of a label at font-size 11 (sans-serif digits ≈ 6.2 px; generous, never clipped).
int text_width(const std::string& s) { return static_cast<int>(s.size() * 6.5) + 2; }

}  // namespace

void write_measures_chart(const std::string& path, const std::string& title,
                          const std::vector<Series>& series) {
  static const char* names[] = {"E", "E_iso^N", "E_conf^N", "E_area %", "max e_iso",
                                "max e_conf", "max e_f²"};
  static const char* colours[] = {"#c0392b", "#2c3e50", "#27ae60", "#8e44ad"};
  const int pw = 220, ph = 160, cols = 4, top = 40;

  // Axes first: the left margin fits the widest y label of any panel.
  double bmax = 0;
  for (const Series& s : series)
    for (const auto& [b, v] : s.points) bmax = std::max(bmax, b);
  const Ticks xt = nice_ticks(0, std::max(bmax, 1e-9));
  Ticks yt[7];
  int left = 30;
  for (int c = 0; c < 7; ++c) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Series& s : series)
      for (const auto& [b, v] : s.points) {
        lo = std::min(lo, v[c]);
        hi = std::max(hi, v[c]);
      }
    if (!std::isfinite(lo)) lo = 0, hi = 1;
    yt[c] = nice_ticks(lo, hi);
    for (int i = 0; i <= yt[c].count(); ++i)
      left = std::max(left, text_width(label(yt[c].at(i), yt[c])) + 10);
  }
  const int gap = 20;  // between a panel and the next one's labels
  const int width = left + cols * (pw + left + gap), height = 2 * (ph + 60) + top + 30;

  std::ostringstream svg;
  svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
      << "' font-family='sans-serif' font-size='11'>\n<rect width='100%' height='100%' fill='white'/>\n"
      << "<text x='10' y='20' font-size='14'>" << title << ": measures against β</text>\n";
  for (int c = 0; c < 7; ++c) {
    const int x0 = left + (c % cols) * (pw + left + gap), y0 = top + (c / cols) * (ph + 60);
    const Ticks& y = yt[c];
    auto X = [&](double b) { return x0 + pw * (b - xt.lo) / (xt.hi - xt.lo); };
    auto Y = [&](double v) { return y0 + ph - ph * (v - y.lo) / (y.hi - y.lo); };
    svg << "<text x='" << x0 << "' y='" << y0 - 8 << "'>" << names[c] << "</text>\n"
        << "<rect x='" << x0 << "' y='" << y0 << "' width='" << pw << "' height='" << ph
        << "' fill='none' stroke='#999'/>\n";
    for (int i = 0; i <= y.count(); ++i)
      svg << "<text x='" << x0 - 4 << "' y='" << Y(y.at(i)) + 4 << "' text-anchor='end'>"
          << label(y.at(i), y) << "</text>\n";
    for (int i = 0; i <= xt.count(); ++i)
      svg << "<text x='" << X(xt.at(i)) << "' y='" << y0 + ph + 14 << "' text-anchor='middle'>"
          << label(xt.at(i), xt) << "</text>\n";
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
  const int lx = left + 3 * (pw + left + gap), ly = top + ph + 60 + 20;
  for (std::size_t k = 0; k < series.size(); ++k)
    svg << "<line x1='" << lx << "' y1='" << ly + 18 * k << "' x2='" << lx + 30 << "' y2='"
        << ly + 18 * k << "' stroke='" << colours[k % 4] << "' stroke-width='2'"
        << (k ? " stroke-dasharray='4 3'" : "") << "/>\n<text x='" << lx + 36 << "' y='"
        << ly + 18 * k + 4 << "'>" << series[k].name << "</text>\n";
  svg << "</svg>\n";
  write_if_changed(path, svg.str());
}

}  // namespace hdeform::report
