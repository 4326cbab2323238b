// libFuzzer target: `hdeform run` job files (client-cli/job_file.h). parse_job must throw
// FileError — and nothing else — on any bad input, never crash, hang or exhaust memory, and
// every job it accepts names only plain output files (no '/', no leading '.').
#include "job_file.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

namespace {

void check_plain(const std::string& part) {
  if (part.empty() || part != hdeform::cli::file_name_part(part) ||
      part.size() > hdeform::cli::kMaxNamePart)
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace hdeform::cli;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    // A folder that does not exist: relative mesh paths never name a file.
    const Job job = parse_job(text, "fuzz.json", "/nonexistent-hdeform-fuzz");
    if (job.meshes.empty() || job.constraints.empty() || job.transforms.empty() ||
        job.betas.empty() || job.item_count() > kMaxJobItems)
      std::abort();
    for (const auto& m : job.meshes) check_plain(m.file_part);
    for (const auto& c : job.constraints) check_plain(c.file_part);
    for (const auto& t : job.transforms) check_plain(t.file_part);
    check_plain(job.summary);
    const std::string f =
        item_file_name(job, job.meshes[0], job.constraints[0], job.transforms[0], job.betas[0]);
    if (!is_plain_file_name(f)) std::abort();
  } catch (const FileError&) {
  }
  return 0;
}
