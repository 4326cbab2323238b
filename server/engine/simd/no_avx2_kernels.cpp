// Built instead of the *_avx2.cpp files where the CPU is not x86-64: their entry points exist
// (guidance.cpp, measures.cpp, vertex_normals.cpp and the tests name them) but are never
// called, since kernel_isa() is then always Isa::generic (cpu_features.h).
#include "engine/simd/guidance_rotation.h"
#include "engine/simd/measure_triangles.h"
#include "engine/simd/vertex_normals_kernels.h"

#include <cstdlib>

namespace hdeform::detail {

std::ptrdiff_t guidance_rotation_avx2(const int*, const double*, const std::complex<double>*,
                                      const double[3], std::ptrdiff_t, std::ptrdiff_t, double*,
                                      double*) {
  std::abort();
}
void vertex_turns_avx2(const double*, std::ptrdiff_t, std::ptrdiff_t, double,
                       std::complex<double>*) {
  std::abort();
}
std::ptrdiff_t measure_triangles_avx2(const int*, const double*, const double*, const double*,
                                      const double*, const double*, std::ptrdiff_t,
                                      std::ptrdiff_t, float*, double*, MeasureSums&) {
  std::abort();
}
void face_weights_avx2(const int*, const double*, std::ptrdiff_t, std::ptrdiff_t, double*) {
  std::abort();
}
void gather_normals_avx2(const int*, const int*, const double*, std::ptrdiff_t, std::ptrdiff_t,
                         double*) {
  std::abort();
}

}  // namespace hdeform::detail
