// horus._core: the C++ runtime as seen from the `horus` Python package.
#include "bindings.hpp"

PYBIND11_MODULE(_core, m) {
  m.doc() = "The C++ core of the horus Python package (use `import horus`).";
  horus::python::bind_scheduler(m);
  horus::python::bind_topics(m);
  horus::python::bind_services(m);
}
