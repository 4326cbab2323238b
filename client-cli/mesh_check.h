// Checks a mesh file's bytes (as GetMesh sends them) for non-finite vertex coordinates
// before the CLI writes them. Pure: no protobuf, no gRPC.
#pragma once

#include "errors.h"

#include <cstddef>
#include <optional>
#include <string_view>

namespace hdeform::cli {

// The number of NaN/Inf vertex coordinates in a mesh file of this format ("glb", "obj",
// "off", "ply"); std::nullopt for a layout this check does not read (binary PLY). Throws
// CliError when the bytes are not a mesh of that format.
std::optional<std::size_t> count_non_finite_coordinates(std::string_view bytes,
                                                        std::string_view format);

// The number of NaN/Inf values among float32 little-endian numbers (Frame.positions).
std::size_t count_non_finite_floats(std::string_view float32_le);

}  // namespace hdeform::cli
