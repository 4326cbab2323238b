// Gives the C library's free memory back to the operating system after a large release (a
// session deleted or expired): glibc keeps freed heap pages below its mmap threshold, so
// without this a deleted 100K session's ≈ 1 GB of matrices stays in the server's RSS.
#pragma once

namespace hdeform::service {

// malloc_trim(0) on glibc; nothing elsewhere. Costs ≈ milliseconds on a large heap.
void release_freed_memory();

}  // namespace hdeform::service
