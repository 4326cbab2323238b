// Numbers in messages for people: the shortest form that reads back to the same double
// ("0.25", "500", "1e+300"), never std::to_string's "500.000000".
#pragma once

#include <charconv>
#include <string>

namespace hdeform {

inline std::string shortest(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace hdeform
