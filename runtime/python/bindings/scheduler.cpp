#include "bindings.hpp"

namespace horus::python {

void bind_scheduler(pybind11::module_& /*m*/) {}

}  // namespace horus::python
