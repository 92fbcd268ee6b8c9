// The parts of the horus._core extension, each in its own source file.
#pragma once

#include <pybind11/pybind11.h>

namespace horus::python {

/// horus._core: Scheduler, node trampolines, the framework clock, logging.
void bind_scheduler(pybind11::module_& m);
/// horus._core: type-erased topics (bytes in, bytes or zero-copy views out).
void bind_topics(pybind11::module_& m);
/// horus._core: send() / try_recv() in C for POD topics whose fields are all scalars.
void bind_pod_fast_path(pybind11::module_& m);
/// horus._core: type-erased service clients and servers.
void bind_services(pybind11::module_& m);
/// horus._core: services, log ring, presence and cleaning, for the `horus` command.
void bind_introspection(pybind11::module_& m);
/// Session recording on horus._core.Scheduler (after bind_scheduler).
void bind_recording(pybind11::module_& m);
/// horus._core: parameters (ParamError, the store's reader, writes, YAML files, the handles of
/// Python nodes' parameters); after the HorusError of the module.
void bind_params(pybind11::module_& m);
/// horus._core: the frame tree, its FrameError classes and transform arithmetic; after HorusError.
void bind_frames(pybind11::module_& m);
/// horus._core: the tensor pool, Image, DepthImage, PointCloud, Tensor and their topics.
void bind_pool(pybind11::module_& m);
// bridges/dds/python/bindings.cpp, built in where Cyclone DDS is (HORUS_PYTHON_DDS).
void bind_dds(pybind11::module_& m);

}  // namespace horus::python
