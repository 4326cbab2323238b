// Measures against β as small-multiple SVG line charts (thesis Figure 7.5's layout).
#pragma once

#include "fixtures/thesis_tables.h"

#include <string>
#include <utility>
#include <vector>

namespace hdeform::report {

struct Series {
  std::string name;
  std::vector<std::pair<double, Columns>> points;  // (β, the seven measures)
};

// One panel per measure; series drawn in distinct colours with a legend.
void write_measures_chart(const std::string& path, const std::string& title,
                          const std::vector<Series>& series);

}  // namespace hdeform::report
