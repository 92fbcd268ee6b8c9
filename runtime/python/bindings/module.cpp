// horus._core: the C++ runtime as seen from the `horus` Python package.
#include "bindings.hpp"
#include "horus/error.hpp"

#ifdef HORUS_PYTHON_VIEW
namespace horus::python {
// bridges/view/python/bindings.cpp, compiled in where the live view is built.
void bind_view(pybind11::module_& m);
}  // namespace horus::python
#endif

PYBIND11_MODULE(_core, m) {
  m.doc() = "The C++ core of the horus Python package (use `import horus`).";
  static pybind11::exception<horus::Error> error(m, "HorusError", PyExc_RuntimeError);
  pybind11::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const horus::Error& e) {
      error(e.what());
    }
  });
  horus::python::bind_scheduler(m);
  horus::python::bind_topics(m);
  horus::python::bind_pod_fast_path(m);
  horus::python::bind_services(m);
  horus::python::bind_introspection(m);
  horus::python::bind_recording(m);
  horus::python::bind_pool(m);
  horus::python::bind_params(m);
  horus::python::bind_frames(m);
#ifdef HORUS_PYTHON_DDS
  auto dds = m.def_submodule("dds",
                             "The DDS bridge's library (bridges/dds/): raw-CDR endpoints "
                             "on Cyclone DDS, CDR plans and pumps.");
  horus::python::bind_dds(dds);
#endif
#ifdef HORUS_PYTHON_VIEW
  auto view = m.def_submodule("view",
                              "The live view's library (bridges/view/): a namespace served over "
                              "the Foxglove WebSocket protocol, with a time set from Python.");
  horus::python::bind_view(view);
#endif
}
