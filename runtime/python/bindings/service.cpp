#include "bindings.hpp"

namespace horus::python {

void bind_services(pybind11::module_& /*m*/) {}

}  // namespace horus::python
