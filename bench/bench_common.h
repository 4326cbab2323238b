// Pieces both benchmarks (engine_bench, service_bench) share: process memory from
// /proc/self/status and the command line with our own --hdeform_smoke flag.
#pragma once

#include <benchmark/benchmark.h>

#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace hdeform::bench {

// A "/proc/self/status" field in kB ("VmRSS", "VmHWM", …); -1 when it is not there.
inline double status_kb(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string line;
  const std::size_t len = std::strlen(key);
  while (std::getline(f, line))
    if (line.compare(0, len, key) == 0 && line.size() > len && line[len] == ':')
      return std::stod(line.substr(len + 1));
  return -1;
}

// Resets VmHWM to the current VmRSS (Linux ≥ 4.0: "5" > clear_refs); false if it could not.
inline bool reset_peak() {
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
  f.flush();
  return f.good();
}

// benchmark::Initialize on the arguments without --hdeform_smoke (sets smoke when given).
// False when there are arguments neither knows (reported): main then returns 1.
inline bool initialize(int argc, char** argv, bool& smoke) {
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strcmp(argv[i], "--hdeform_smoke") == 0)
      smoke = true;
    else
      args.push_back(argv[i]);
  }
  int nargs = static_cast<int>(args.size());
  benchmark::Initialize(&nargs, args.data());
  return !benchmark::ReportUnrecognizedArguments(nargs, args.data());
}

}  // namespace hdeform::bench
