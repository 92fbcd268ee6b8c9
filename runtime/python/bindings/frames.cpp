// horus._core: the namespace's frame tree (horus/frames.hpp) and its transform arithmetic, for
// horus.FrameTree (horus/_frames.py). Transforms cross as ((x, y, z), (qx, qy, qz, qw)) tuples,
// stamps as integer nanoseconds and durations as float seconds; every C++ error kind becomes its
// own subclass of FrameError, with the frame, amount or authority it names as attributes.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "horus/frames.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

using Translation = std::array<double, 3>;
using Rotation = std::array<double, 4>;
using TransformTuple = std::tuple<Translation, Rotation>;

Transform transform_of(const Translation& translation, const Rotation& rotation) {
  return {{translation[0], translation[1], translation[2]},
          {rotation[0], rotation[1], rotation[2], rotation[3]}};
}

Translation tuple_of(const Vector3& v) { return {v.x, v.y, v.z}; }

TransformTuple tuple_of(const Transform& t) {
  return {tuple_of(t.translation), {t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w}};
}

std::optional<std::chrono::nanoseconds> stamp_of(std::optional<std::int64_t> ns) {
  if (!ns) return std::nullopt;
  return std::chrono::nanoseconds(*ns);
}

/// Seconds as a duration; the Python side has checked them finite and not negative.
std::chrono::nanoseconds duration_of(double seconds) {
  return std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(seconds * 1e9)));
}

double seconds_of(std::chrono::nanoseconds duration) { return duration.count() / 1e9; }

py::tuple stamped_tuple(const StampedTransform& stamped) {
  return py::make_tuple(stamped.parent, stamped.child, stamped.stamp.count(),
                        tuple_of(stamped.transform));
}

/// Applies `apply` to every row of an (N, 3) array of float64 (a point cloud), GIL released.
template <typename Apply>
py::array_t<double> each_row(
    const py::array_t<double, py::array::c_style | py::array::forcecast>& rows, Apply apply) {
  if (rows.ndim() != 2 || rows.shape(1) != 3) {
    throw py::value_error(
        "expected an array of shape (N, 3), got one of " +
        py::str(py::cast(std::vector<py::ssize_t>(rows.shape(), rows.shape() + rows.ndim())))
            .cast<std::string>());
  }
  const py::ssize_t count = rows.shape(0);
  py::array_t<double> result({count, py::ssize_t{3}});
  const double* in = rows.data();
  double* out = result.mutable_data();
  {
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < count; ++i) {
      const Vector3 mapped = apply(Vector3{in[3 * i], in[3 * i + 1], in[3 * i + 2]});
      out[3 * i] = mapped.x;
      out[3 * i + 1] = mapped.y;
      out[3 * i + 2] = mapped.z;
    }
  }
  return result;
}

/// Raises `type(message)` with `attributes` set on the instance.
void raise_with(const py::object& type, const char* message, const py::dict& attributes) {
  py::object instance = type(message);
  for (const auto& [key, value] : attributes) {
    instance.attr(key) = value;
  }
  PyErr_SetObject(type.ptr(), instance.ptr());
}

}  // namespace

void bind_frames(py::module_& m) {
  static py::exception<FrameError> frame_error(m, "FrameError", m.attr("HorusError").ptr());
  static py::exception<ExtrapolationError> extrapolation(m, "ExtrapolationError", frame_error);
  static py::exception<UnknownFrameError> unknown(m, "UnknownFrameError", frame_error);
  static py::exception<DisconnectedFramesError> disconnected(m, "DisconnectedFramesError",
                                                             frame_error);
  static py::exception<StaleFrameError> stale(m, "StaleFrameError", frame_error);
  static py::exception<InvalidTransformError> invalid(m, "InvalidTransformError", frame_error);
  static py::exception<FrameCycleError> cycle(m, "FrameCycleError", frame_error);
  static py::exception<FrameAuthorityError> authority(m, "FrameAuthorityError", frame_error);
  static py::exception<FrameCapacityError> capacity(m, "FrameCapacityError", frame_error);
  // Tried before the translator of every horus::Error (module.cpp), registered earlier.
  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const ExtrapolationError& e) {
      raise_with(extrapolation, e.what(),
                 py::dict(py::arg("frame") = e.frame(), py::arg("into_past") = e.into_past(),
                          py::arg("by") = seconds_of(e.by())));
    } catch (const UnknownFrameError& e) {
      raise_with(unknown, e.what(),
                 py::dict(py::arg("frame") = e.frame(), py::arg("closest") = e.closest()));
    } catch (const StaleFrameError& e) {
      raise_with(stale, e.what(),
                 py::dict(py::arg("frame") = e.frame(), py::arg("by") = seconds_of(e.by())));
    } catch (const FrameAuthorityError& e) {
      raise_with(authority, e.what(),
                 py::dict(py::arg("pid") = e.pid(), py::arg("program") = e.program()));
    } catch (const DisconnectedFramesError& e) {
      disconnected(e.what());
    } catch (const InvalidTransformError& e) {
      invalid(e.what());
    } catch (const FrameCycleError& e) {
      cycle(e.what());
    } catch (const FrameCapacityError& e) {
      capacity(e.what());
    } catch (const FrameError& e) {
      frame_error(e.what());
    }
  });

  py::class_<FrameTree>(m, "FrameTree", "One namespace's frame tree (horus/frames.hpp)")
      .def(py::init([](const std::string& namespace_name, double history_s) {
             FrameTreeOptions options;
             options.namespace_name = namespace_name;
             options.history = duration_of(history_s);
             return FrameTree(std::move(options));
           }),
           py::arg("namespace_name"), py::arg("history_s"))
      .def(
          "set_transform",
          [](FrameTree& tree, const std::string& parent, const std::string& child,
             const Translation& translation, const Rotation& rotation, std::int64_t stamp_ns) {
            tree.set_transform(parent, child, transform_of(translation, rotation),
                               std::chrono::nanoseconds(stamp_ns));
          },
          py::arg("parent"), py::arg("child"), py::arg("translation"), py::arg("rotation"),
          py::arg("stamp_ns"))
      .def(
          "set_static_transform",
          [](FrameTree& tree, const std::string& parent, const std::string& child,
             const Translation& translation, const Rotation& rotation) {
            tree.set_static_transform(parent, child, transform_of(translation, rotation));
          },
          py::arg("parent"), py::arg("child"), py::arg("translation"), py::arg("rotation"))
      .def(
          "lookup_stamped",
          [](const FrameTree& tree, const std::string& target, const std::string& source,
             std::optional<std::int64_t> time_ns, std::optional<double> max_age_s) {
            std::optional<std::chrono::nanoseconds> max_age;
            if (max_age_s) max_age = duration_of(*max_age_s);
            return stamped_tuple(tree.lookup_stamped(target, source, stamp_of(time_ns), max_age));
          },
          py::arg("target"), py::arg("source"), py::arg("time_ns"), py::arg("max_age_s"))
      .def(
          "why_not",
          [](const FrameTree& tree, const std::string& target, const std::string& source,
             std::optional<std::int64_t> time_ns) -> std::optional<std::string> {
            std::string why;
            if (tree.can_lookup(target, source, stamp_of(time_ns), &why)) return std::nullopt;
            return why;
          },
          py::arg("target"), py::arg("source"), py::arg("time_ns"),
          "None when lookup would answer, else the message it would raise")
      .def(
          "wait_for",
          [](const FrameTree& tree, const std::string& target, const std::string& source,
             std::optional<std::int64_t> time_ns, double timeout_s) {
            py::gil_scoped_release release;
            return tree.wait_for(target, source, stamp_of(time_ns), duration_of(timeout_s));
          },
          py::arg("target"), py::arg("source"), py::arg("time_ns"), py::arg("timeout_s"))
      .def(
          "frames",
          [](const FrameTree& tree) {
            py::list rows;
            for (const FrameInfo& info : tree.frames()) {
              rows.append(py::make_tuple(info.name, info.parent, info.is_static, info.authority_pid,
                                         info.authority_program, info.authority_alive,
                                         info.oldest.count(), info.latest.count(), info.updates));
            }
            return rows;
          })
      .def(
          "history",
          [](const FrameTree& tree, const std::string& frame) {
            py::list rows;
            for (const StampedTransform& entry : tree.history(frame)) {
              rows.append(stamped_tuple(entry));
            }
            return rows;
          },
          py::arg("frame"))
      .def("change_count", &FrameTree::change_count)
      .def(
          "wait_for_change",
          [](const FrameTree& tree, std::uint32_t seen, double timeout_s) {
            py::gil_scoped_release release;
            return tree.wait_for_change(seen, duration_of(timeout_s));
          },
          py::arg("seen"), py::arg("timeout_s"))
      .def("history_s", [](const FrameTree& tree) { return seconds_of(tree.history_duration()); })
      .def("as_text", &FrameTree::as_text)
      .def("as_dot", &FrameTree::as_dot)
      .def("path", &FrameTree::path);

  m.def(
      "remove_frame_tree",
      [](const std::string& namespace_name) { return remove_frame_tree(namespace_name); },
      py::arg("namespace_name"));
  m.def(
      "frame_tree_exists",
      [](const std::string& namespace_name) { return frame_tree_exists(namespace_name); },
      py::arg("namespace_name"));
  m.def(
      "compose_transforms",
      [](const Translation& at, const Rotation& ar, const Translation& bt, const Rotation& br) {
        return tuple_of(compose(transform_of(at, ar), transform_of(bt, br)));
      },
      "`a` after `b`: maps through `b` first, then `a`");
  m.def("inverse_transform", [](const Translation& translation, const Rotation& rotation) {
    return tuple_of(inverse(transform_of(translation, rotation)));
  });
  m.def("interpolate_transforms", [](const Translation& at, const Rotation& ar,
                                     const Translation& bt, const Rotation& br, double fraction) {
    return tuple_of(interpolate(transform_of(at, ar), transform_of(bt, br), fraction));
  });
  m.def("transform_point",
        [](const Translation& translation, const Rotation& rotation, const Translation& point) {
          const Vector3 p{point[0], point[1], point[2]};
          return tuple_of(horus::transform_point(transform_of(translation, rotation), p));
        });
  m.def("transform_vector",
        [](const Translation& translation, const Rotation& rotation, const Translation& vector) {
          const Vector3 v{vector[0], vector[1], vector[2]};
          return tuple_of(horus::transform_vector(transform_of(translation, rotation), v));
        });
  m.def("transform_pose", [](const Translation& translation, const Rotation& rotation,
                             const Translation& position, const Rotation& orientation) {
    return tuple_of(horus::transform_pose(transform_of(translation, rotation),
                                          transform_of(position, orientation)));
  });
  m.def("transform_points",
        [](const Translation& translation, const Rotation& rotation,
           const py::array_t<double, py::array::c_style | py::array::forcecast>& points) {
          const Transform transform = transform_of(translation, rotation);
          return each_row(points,
                          [&](const Vector3& p) { return horus::transform_point(transform, p); });
        });
  m.def("transform_vectors",
        [](const Translation& translation, const Rotation& rotation,
           const py::array_t<double, py::array::c_style | py::array::forcecast>& vectors) {
          const Transform transform = transform_of(translation, rotation);
          return each_row(vectors,
                          [&](const Vector3& v) { return horus::transform_vector(transform, v); });
        });
}

}  // namespace horus::python
