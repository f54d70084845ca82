// Built instead of gravity/cuda/*.cu when no CUDA compiler was found.
#include "gravity/cuda.hpp"

namespace rubble::gravity::cuda {

bool compiled() { return false; }
int device_count() { return 0; }
bool available() { return false; }
std::string unavailable_reason() {
  return "rubble_gravity was built without the CUDA backend (no CUDA compiler at configure time)";
}
void direct_sum(const GravityOptions&, std::span<const double>, std::span<const double>, std::span<double>,
                std::span<double>) {
  throw BackendUnavailable("CUDA backend: " + unavailable_reason());
}
FieldTimings tree_field(const GravityOptions&, std::span<const double>, std::span<const double>, std::span<double>,
                        std::span<double>) {
  throw BackendUnavailable("CUDA backend: " + unavailable_reason());
}

FieldTimings tree_field_checked(const GravityOptions&, std::span<const double>, std::span<const double>,
                                std::span<double>, std::span<double>) {
  throw BackendUnavailable("CUDA backend: " + unavailable_reason());
}

detail::BuiltTree built_tree(const GravityOptions&, std::span<const double>, std::span<const double>) {
  throw BackendUnavailable("CUDA backend: " + unavailable_reason());
}

}  // namespace rubble::gravity::cuda
