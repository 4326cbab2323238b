// A small headless renderer for the reproduction report: orthographic z-buffer
// rasterization of a triangle mesh, flat-shaded, coloured per triangle, written as PNG.
#pragma once

#include "engine/mesh/mesh.h"

#include <Eigen/Core>

#include <string>

namespace hdeform::report {

struct View {
  Eigen::Vector3d direction{1.0, -2.0, 1.0};  // from the model towards the eye
  Eigen::Vector3d up{0.0, 0.0, 1.0};
  int size = 420;                             // pixels (square)
};

// Colour map of the thesis's figures: linear from white (0) to red (≥ `truncate`).
// truncate = max value gives the linear mapping (LM), smaller the truncated one (TLM).
Eigen::Vector3f energy_colour(double value, double truncate);

// Renders V/F with per-triangle colours (m×3, in [0, 1]) and writes a PNG (unless the file
// already has these pixels: write_if_changed.h).
void render_png(const std::string& path, const Vertices& V, const Triangles& F,
                const Eigen::MatrixX3f& colours, const View& view);

}  // namespace hdeform::report
