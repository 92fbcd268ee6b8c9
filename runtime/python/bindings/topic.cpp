#include "bindings.hpp"

namespace horus::python {

void bind_topics(pybind11::module_& /*m*/) {}

}  // namespace horus::python
