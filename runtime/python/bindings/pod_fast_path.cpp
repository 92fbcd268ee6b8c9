// horus._core.PodFastPath: send() and try_recv() of a topic whose message is POD with scalar
// fields only (integers, floats, bool: CmdVel and the like), as plain CPython functions. A typed
// hop through the general path costs a pybind11 dispatch each way plus to_bytes() / from_bytes()
// (a bytearray, a struct call, a bytes copy, an object); here send() reads the message's slots
// and writes the C++ struct bytes in one pass, and try_recv() builds the message object straight
// from the received bytes. Anything this path does not take as is (a subclass, an int too large,
// a numpy scalar, an unset field) goes through the message's own encoder, so the values accepted
// and the errors raised stay exactly the general path's.
#include <pybind11/stl.h>
#include <structmember.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <optional>
#include <span>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "bindings.hpp"
#include "horus/error.hpp"
#include "horus/raw_topic.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

// The bytes are the C++ struct's: the struct module's "<" layout is the native one only here.
static_assert(std::endian::native == std::endian::little, "POD bytes assume a little-endian host");

/// One scalar field: where its value lives in the Python object (a __slots__ member) and in the
/// C++ struct, and its struct-module format character.
struct ScalarField {
  Py_ssize_t slot = 0;
  std::uint32_t offset = 0;
  char format = 0;
};

std::size_t width(char format) {
  switch (format) {
    case '?':
    case 'b':
    case 'B':
      return 1;
    case 'h':
    case 'H':
      return 2;
    case 'i':
    case 'I':
    case 'f':
      return 4;
    case 'q':
    case 'Q':
    case 'd':
      return 8;
    default:
      return 0;
  }
}

template <class T>
void store(std::byte* out, T value) noexcept {
  std::memcpy(out, &value, sizeof(T));
}

template <class T>
T load(const std::byte* in) noexcept {
  T value;
  std::memcpy(&value, in, sizeof(T));
  return value;
}

/// A Python int (or bool) that fits T, stored as T; false (no error set) otherwise.
template <class T>
bool pack_integer(PyObject* v, std::byte* out) noexcept {
  if (!PyLong_Check(v)) return false;
  if constexpr (std::is_signed_v<T>) {
    int overflow = 0;
    const long long value = PyLong_AsLongLongAndOverflow(v, &overflow);
    if (overflow != 0 || (value == -1 && PyErr_Occurred() != nullptr)) {
      PyErr_Clear();
      return false;
    }
    if (value < std::numeric_limits<T>::min() || value > std::numeric_limits<T>::max()) {
      return false;
    }
    store(out, static_cast<T>(value));
  } else {
    const unsigned long long value = PyLong_AsUnsignedLongLong(v);  // raises for negatives
    if (value == static_cast<unsigned long long>(-1) && PyErr_Occurred() != nullptr) {
      PyErr_Clear();
      return false;
    }
    if (value > std::numeric_limits<T>::max()) return false;
    store(out, static_cast<T>(value));
  }
  return true;
}

/// A float or int as a double, as struct's "d" and "f" take them; false (no error set) otherwise.
bool real_value(PyObject* v, double& out) noexcept {
  if (PyFloat_CheckExact(v)) {
    out = PyFloat_AS_DOUBLE(v);
    return true;
  }
  if (!PyLong_Check(v)) return false;
  out = PyLong_AsDouble(v);
  if (out == -1.0 && PyErr_Occurred() != nullptr) {
    PyErr_Clear();
    return false;
  }
  return true;
}

/// Writes one field's value; false (no error set) when the general encoder must judge it.
bool pack_field(PyObject* v, char format, std::byte* out) noexcept {
  double d = 0.0;
  switch (format) {
    case '?':
      // True and False only: another object's truth is its __bool__, Python code that could
      // send on this topic while the staging buffer is half written.
      if (v != Py_True && v != Py_False) return false;
      store<std::uint8_t>(out, v == Py_True ? 1 : 0);
      return true;
    case 'b':
      return pack_integer<std::int8_t>(v, out);
    case 'h':
      return pack_integer<std::int16_t>(v, out);
    case 'i':
      return pack_integer<std::int32_t>(v, out);
    case 'q':
      return pack_integer<std::int64_t>(v, out);
    case 'B':
      return pack_integer<std::uint8_t>(v, out);
    case 'H':
      return pack_integer<std::uint16_t>(v, out);
    case 'I':
      return pack_integer<std::uint32_t>(v, out);
    case 'Q':
      return pack_integer<std::uint64_t>(v, out);
    case 'f': {
      if (!real_value(v, d)) return false;
      const auto single = static_cast<float>(d);
      if (std::isinf(single) && !std::isinf(d)) return false;  // out of range: the encoder says so
      store(out, single);
      return true;
    }
    case 'd':
      if (!real_value(v, d)) return false;
      store(out, d);
      return true;
    default:
      return false;
  }
}

/// A new reference to the value of one field read from the struct bytes (as struct unpacks it).
PyObject* unpack_field(const std::byte* in, char format) noexcept {
  switch (format) {
    case '?':
      return PyBool_FromLong(load<std::uint8_t>(in) != 0);
    case 'b':
      return PyLong_FromLong(load<std::int8_t>(in));
    case 'h':
      return PyLong_FromLong(load<std::int16_t>(in));
    case 'i':
      return PyLong_FromLong(load<std::int32_t>(in));
    case 'q':
      return PyLong_FromLongLong(load<std::int64_t>(in));
    case 'B':
      return PyLong_FromUnsignedLong(load<std::uint8_t>(in));
    case 'H':
      return PyLong_FromUnsignedLong(load<std::uint16_t>(in));
    case 'I':
      return PyLong_FromUnsignedLong(load<std::uint32_t>(in));
    case 'Q':
      return PyLong_FromUnsignedLongLong(load<std::uint64_t>(in));
    case 'f':
      return PyFloat_FromDouble(static_cast<double>(load<float>(in)));
    case 'd':
      return PyFloat_FromDouble(load<double>(in));
    default:
      PyErr_SetString(PyExc_SystemError, "horus: a scalar field of unknown format");
      return nullptr;
  }
}

/// What a PodFastPath object owns besides its Python header.
struct State {
  py::object core;            // the horus._core.Topic that owns `topic`
  RawTopic* topic = nullptr;  // owned by `core`
  py::object cls;             // the message class (exact type: a subclass takes the general path)
  py::object encode;          // msg -> bytes, raising the general path's errors
  py::object view;            // cls.view, for try_recv(view=True)
  std::vector<ScalarField> fields;
  std::vector<std::byte> staging;  // the struct bytes being sent (padding stays zero)
};

struct PodFastPath {
  PyObject_HEAD State state;
};

State& state_of(PyObject* self) { return reinterpret_cast<PodFastPath*>(self)->state; }

PyObject*& slot_of(PyObject* msg, const ScalarField& field) {
  return *reinterpret_cast<PyObject**>(reinterpret_cast<char*>(msg) + field.slot);
}

/// The struct bytes of `msg` into the staging buffer; false (no error set) when a value is not
/// one this path takes as is.
bool pack(State& s, PyObject* msg) noexcept {
  if (Py_TYPE(msg) != reinterpret_cast<PyTypeObject*>(s.cls.ptr())) return false;
  for (const ScalarField& field : s.fields) {
    PyObject* value = slot_of(msg, field);
    if (value == nullptr || !pack_field(value, field.format, s.staging.data() + field.offset)) {
      return false;
    }
  }
  return true;
}

PyObject* fast_send(PyObject* self, PyObject* msg) {
  State& s = state_of(self);
  if (pack(s, msg)) {
    return PyBool_FromLong(s.topic->send(s.staging));
  }
  PyObject* encoded = PyObject_CallOneArg(s.encode.ptr(), msg);
  if (encoded == nullptr) return nullptr;
  Py_buffer buffer;
  if (PyObject_GetBuffer(encoded, &buffer, PyBUF_SIMPLE) != 0) {
    Py_DECREF(encoded);
    return nullptr;
  }
  const bool sent = s.topic->send(
      {static_cast<const std::byte*>(buffer.buf), static_cast<std::size_t>(buffer.len)});
  PyBuffer_Release(&buffer);
  Py_DECREF(encoded);
  return PyBool_FromLong(sent);
}

/// A new message object made from the received struct bytes.
PyObject* unpack(State& s, const std::byte* bytes) noexcept {
  // Every value first: ints and floats are not garbage-collected objects, so making them runs
  // no Python code, while allocating the message may start a collection whose finalizers could
  // receive on this topic and overwrite `bytes`.
  constexpr std::size_t kOnStack = 16;  // fields; CmdVel has 3, the largest standard one 10
  std::array<PyObject*, kOnStack> on_stack{};
  std::vector<PyObject*> on_heap;
  PyObject** values = on_stack.data();
  if (s.fields.size() > kOnStack) {
    on_heap.resize(s.fields.size());
    values = on_heap.data();
  }
  std::size_t made = 0;
  for (; made < s.fields.size(); ++made) {
    values[made] = unpack_field(bytes + s.fields[made].offset, s.fields[made].format);
    if (values[made] == nullptr) break;
  }
  auto* type = reinterpret_cast<PyTypeObject*>(s.cls.ptr());
  PyObject* msg = made == s.fields.size() ? type->tp_alloc(type, 0) : nullptr;
  if (msg == nullptr) {
    for (std::size_t i = 0; i < made; ++i) Py_DECREF(values[i]);
    return nullptr;
  }
  for (std::size_t i = 0; i < made; ++i) {
    slot_of(msg, s.fields[i]) = values[i];  // a fresh object: the slot was empty
  }
  return msg;
}

/// try_recv(*, view=False): the next message (or a view over this handle's receive buffer), or
/// None.
PyObject* fast_try_recv(PyObject* self, PyObject* const* args, Py_ssize_t nargs,
                        PyObject* kwnames) {
  bool view = false;
  const Py_ssize_t nkw = kwnames == nullptr ? 0 : PyTuple_GET_SIZE(kwnames);
  if (nargs != 0 || nkw > 1 ||
      (nkw == 1 && PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, 0), "view") != 0)) {
    PyErr_SetString(PyExc_TypeError, "try_recv() takes only the keyword argument 'view'");
    return nullptr;
  }
  if (nkw == 1) {
    const int truth = PyObject_IsTrue(args[0]);
    if (truth < 0) return nullptr;
    view = truth != 0;
  }
  State& s = state_of(self);
  const std::ptrdiff_t size = s.topic->try_recv();
  if (size < 0) {
    Py_RETURN_NONE;
  }
  const std::span<std::byte> bytes = s.topic->received(static_cast<std::size_t>(size));
  if (!view) {
    return unpack(s, bytes.data());
  }
  PyObject* memory = PyMemoryView_FromMemory(reinterpret_cast<char*>(bytes.data()),
                                             static_cast<Py_ssize_t>(bytes.size()), PyBUF_WRITE);
  if (memory == nullptr) return nullptr;
  PyObject* out = PyObject_CallOneArg(s.view.ptr(), memory);
  Py_DECREF(memory);
  return out;
}

void dealloc(PyObject* self) {
  PyTypeObject* type = Py_TYPE(self);
  state_of(self).~State();
  type->tp_free(self);
  Py_DECREF(type);  // instances of a heap type hold a reference to it
}

PyMethodDef methods[] = {
    {"send", fast_send, METH_O,
     "send(msg): publishes msg (the general path's values and errors); False when nothing was "
     "published."},
    {"try_recv", reinterpret_cast<PyCFunction>(reinterpret_cast<void (*)()>(fast_try_recv)),
     METH_FASTCALL | METH_KEYWORDS,
     "try_recv(*, view=False): the next message, a view over the receive buffer, or None."},
    {nullptr, nullptr, 0, nullptr}};

PyType_Slot slots[] = {{Py_tp_dealloc, reinterpret_cast<void*>(dealloc)},
                       {Py_tp_methods, methods},
                       {Py_tp_doc, const_cast<char*>("send() and try_recv() of a topic whose "
                                                     "message has scalar fields only, in C.")},
                       {0, nullptr}};

PyType_Spec spec = {"horus._core.PodFastPath", sizeof(PodFastPath), 0,
                    Py_TPFLAGS_DEFAULT | Py_TPFLAGS_DISALLOW_INSTANTIATION, slots};

/// Where the value of the field `name` sits in an instance of `cls`: its writable __slots__
/// member; nothing when the class keeps it some other way (a subclass's property, say).
std::optional<Py_ssize_t> member_offset(const py::handle& cls, const std::string& name) {
  const py::object descriptor = py::getattr(cls, name.c_str(), py::none());
  if (!Py_IS_TYPE(descriptor.ptr(), &PyMemberDescr_Type) ||
      PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(cls.ptr()),
                       PyDescr_TYPE(descriptor.ptr())) == 0) {
    return std::nullopt;
  }
  const PyMemberDef* member = reinterpret_cast<PyMemberDescrObject*>(descriptor.ptr())->d_member;
  if (member->type != T_OBJECT_EX || (member->flags & READONLY) != 0) {
    return std::nullopt;
  }
  return member->offset;
}

}  // namespace

void bind_pod_fast_path(py::module_& m) {
  auto* type = reinterpret_cast<PyTypeObject*>(PyType_FromSpec(&spec));
  if (type == nullptr) throw py::error_already_set();
  m.add_object("PodFastPath", reinterpret_cast<PyObject*>(type));
  m.def(
      "pod_fast_path",
      [type](py::object core, py::type cls, std::size_t size,
             const std::vector<std::tuple<std::string, std::string, std::uint32_t>>& fields,
             py::object encode) -> py::object {
        // The objects try_recv() makes are allocated as object.__new__ would: only for classes
        // that keep it (a user's subclass may not).
        if (reinterpret_cast<PyTypeObject*>(cls.ptr())->tp_new != PyBaseObject_Type.tp_new) {
          return py::none();
        }
        State state;
        state.core = core;
        state.topic = core.cast<RawTopic*>();
        state.cls = cls;
        state.encode = std::move(encode);
        state.view = cls.attr("view");
        state.staging.resize(size);
        for (const auto& [name, format, offset] : fields) {
          if (format.size() != 1 || width(format[0]) == 0 || offset + width(format[0]) > size) {
            throw Error("PodFastPath: field '" + name + "' (format '" + format + "', offset " +
                        std::to_string(offset) + ") does not fit a " + std::to_string(size) +
                        "-byte struct");
          }
          const std::optional<Py_ssize_t> slot = member_offset(cls, name);
          if (!slot) return py::none();
          state.fields.push_back({*slot, offset, format[0]});
        }
        PyObject* self = type->tp_alloc(type, 0);
        if (self == nullptr) throw py::error_already_set();
        new (&state_of(self)) State(std::move(state));
        return py::reinterpret_steal<py::object>(self);
      },
      py::arg("core"), py::arg("cls"), py::arg("size"), py::arg("fields"), py::arg("encode"),
      "send() and try_recv() in C for `core` (a Topic) carrying `cls`, a POD message of `size` "
      "bytes whose fields are all scalars: (name, struct format, offset). None when `cls` does "
      "not keep its fields in __slots__ or has a __new__ of its own: the general path serves "
      "it.");
}

}  // namespace horus::python
