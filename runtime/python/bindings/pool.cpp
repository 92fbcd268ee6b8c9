// horus._core: the tensor pool and its types (Image, DepthImage, PointCloud, Tensor) and their
// topics. The Python objects wrap the C++ ones: numpy.asarray(x) (buffer protocol) and
// x.__dlpack__() export the pool memory itself, read-only for a received value.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <chrono>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "horus/depth_image.hpp"
#include "horus/image.hpp"
#include "horus/point_cloud.hpp"
#include "horus/tensor.hpp"
#include "horus/tensor_pool.hpp"

namespace py = pybind11;

namespace horus::python {

namespace {

// ---- Array description: what the buffer protocol and DLPack export --------------------------

/// DLPack's element type codes.
enum DlTypeCode : std::uint8_t { kDlInt = 0, kDlUInt = 1, kDlFloat = 2 };

struct ArrayLayout {
  std::string format;  // struct-module format of one element
  std::size_t itemsize = 0;
  DlTypeCode code = kDlUInt;
  std::vector<py::ssize_t> shape;
  std::vector<py::ssize_t> strides;  // bytes
};

ArrayLayout dtype_layout(msg::TensorDtype dtype) {
  switch (dtype) {
    case msg::TensorDtype::F32:
      return {"f", 4, kDlFloat, {}, {}};
    case msg::TensorDtype::F64:
      return {"d", 8, kDlFloat, {}, {}};
    case msg::TensorDtype::F16:
      return {"e", 2, kDlFloat, {}, {}};
    case msg::TensorDtype::U8:
      return {"B", 1, kDlUInt, {}, {}};
    case msg::TensorDtype::U16:
      return {"H", 2, kDlUInt, {}, {}};
    case msg::TensorDtype::U32:
      return {"I", 4, kDlUInt, {}, {}};
    case msg::TensorDtype::U64:
      return {"Q", 8, kDlUInt, {}, {}};
    case msg::TensorDtype::I8:
      return {"b", 1, kDlInt, {}, {}};
    case msg::TensorDtype::I16:
      return {"h", 2, kDlInt, {}, {}};
    case msg::TensorDtype::I32:
      return {"i", 4, kDlInt, {}, {}};
    case msg::TensorDtype::I64:
      return {"q", 8, kDlInt, {}, {}};
  }
  throw Error("unknown tensor dtype " + std::to_string(static_cast<unsigned>(dtype)));
}

/// The element type of an encoding's channels.
msg::TensorDtype encoding_dtype(ImageEncoding encoding) {
  switch (encoding) {
    case ImageEncoding::Mono16:
    case ImageEncoding::Depth16:
      return msg::TensorDtype::U16;
    case ImageEncoding::Mono32F:
    case ImageEncoding::Rgb32F:
      return msg::TensorDtype::F32;
    default:
      return msg::TensorDtype::U8;
  }
}

ArrayLayout layout_of(const Image& image) {
  ArrayLayout layout = dtype_layout(encoding_dtype(image.encoding()));
  const auto item = static_cast<py::ssize_t>(layout.itemsize);
  layout.shape = {image.height(), image.width()};
  layout.strides = {image.step(), static_cast<py::ssize_t>(image.bytes_per_pixel())};
  if (image.channels() > 1) {
    layout.shape.push_back(image.channels());
    layout.strides.push_back(item);
  }
  return layout;
}

ArrayLayout layout_of(const DepthImage& depth) {
  ArrayLayout layout = dtype_layout(depth.dtype());
  const auto item = static_cast<py::ssize_t>(layout.itemsize);
  layout.shape = {depth.height(), depth.width()};
  layout.strides = {item * depth.width(), item};
  return layout;
}

ArrayLayout layout_of(const PointCloud& cloud) {
  ArrayLayout layout = dtype_layout(cloud.dtype());
  const auto item = static_cast<py::ssize_t>(layout.itemsize);
  layout.shape = {static_cast<py::ssize_t>(cloud.point_count()), cloud.fields_per_point()};
  layout.strides = {item * cloud.fields_per_point(), item};
  return layout;
}

ArrayLayout layout_of(const Tensor& tensor) {
  ArrayLayout layout = dtype_layout(tensor.dtype());
  for (std::size_t i = 0; i < tensor.ndim(); ++i) {
    layout.shape.push_back(static_cast<py::ssize_t>(tensor.shape()[i]));
    layout.strides.push_back(static_cast<py::ssize_t>(tensor.strides()[i]));
  }
  return layout;
}

template <class T>
py::buffer_info buffer_of(T& value) {
  if (!value.valid()) {
    throw Error("this value is empty (moved from)");
  }
  ArrayLayout layout = layout_of(value);
  return py::buffer_info(const_cast<std::uint8_t*>(value.data().data()),
                         static_cast<py::ssize_t>(layout.itemsize), layout.format,
                         static_cast<py::ssize_t>(layout.shape.size()), layout.shape,
                         layout.strides, !value.writable());
}

// ---- DLPack: the unversioned ABI every consumer reads, and 1.0's, which has a read-only flag --

struct DLDevice {
  std::int32_t device_type;
  std::int32_t device_id;
};
struct DLDataType {
  std::uint8_t code;
  std::uint8_t bits;
  std::uint16_t lanes;
};
struct DLTensor {
  void* data;
  DLDevice device;
  std::int32_t ndim;
  DLDataType dtype;
  std::int64_t* shape;
  std::int64_t* strides;  // elements, not bytes
  std::uint64_t byte_offset;
};
struct DLManagedTensor {
  DLTensor dl_tensor;
  void* manager_ctx;
  void (*deleter)(DLManagedTensor* self);
};
struct DLPackVersion {
  std::uint32_t major;
  std::uint32_t minor;
};
struct DLManagedTensorVersioned {
  DLPackVersion version;
  void* manager_ctx;
  void (*deleter)(DLManagedTensorVersioned* self);
  std::uint64_t flags;
  DLTensor dl_tensor;
};
constexpr std::int32_t kDlCpu = 1;
constexpr DLPackVersion kDlpackVersion{1, 0};
constexpr std::uint64_t kDlpackReadOnly = 1;  // DLPACK_FLAG_BITMASK_READ_ONLY

/// A consumer renames a capsule "used_" + this name and calls the deleter itself.
template <class Managed>
constexpr const char* kCapsuleName = "dltensor";
template <>
constexpr const char* kCapsuleName<DLManagedTensorVersioned> = "dltensor_versioned";

/// What a DLPack capsule owns: a reference on the value's block and the shape arrays.
template <class T, class Managed>
struct DlpackOwner {
  Managed managed{};
  T value;
  std::vector<std::int64_t> shape;
  std::vector<std::int64_t> strides;
};

template <class Managed, class T>
py::capsule to_dlpack(const T& value) {
  if (!value.valid()) {
    throw Error("this value is empty (moved from)");
  }
  const ArrayLayout layout = layout_of(value);
  auto owner = std::make_unique<DlpackOwner<T, Managed>>();
  owner->value = value;
  for (std::size_t i = 0; i < layout.shape.size(); ++i) {
    owner->shape.push_back(layout.shape[i]);
    owner->strides.push_back(layout.strides[i] / static_cast<py::ssize_t>(layout.itemsize));
  }
  DLTensor& tensor = owner->managed.dl_tensor;
  tensor.data = const_cast<std::uint8_t*>(owner->value.data().data());
  tensor.device = {kDlCpu, 0};
  tensor.ndim = static_cast<std::int32_t>(owner->shape.size());
  tensor.dtype = {layout.code, static_cast<std::uint8_t>(layout.itemsize * 8), 1};
  tensor.shape = owner->shape.data();
  tensor.strides = owner->strides.data();
  tensor.byte_offset = 0;
  if constexpr (std::is_same_v<Managed, DLManagedTensorVersioned>) {
    owner->managed.version = kDlpackVersion;
    owner->managed.flags = value.writable() ? 0 : kDlpackReadOnly;
  }
  owner->managed.manager_ctx = owner.get();
  owner->managed.deleter = [](Managed* self) {
    delete static_cast<DlpackOwner<T, Managed>*>(self->manager_ctx);
  };
  Managed* managed = &owner.release()->managed;
  // An unconsumed capsule (still under its own name) is freed here.
  return py::capsule(managed, kCapsuleName<Managed>, [](PyObject* capsule) {
    if (PyCapsule_IsValid(capsule, kCapsuleName<Managed>) != 0) {
      auto* unused = static_cast<Managed*>(PyCapsule_GetPointer(capsule, kCapsuleName<Managed>));
      unused->deleter(unused);
    }
  });
}

/// The array API's __dlpack__: a versioned capsule (which can say "read-only") for a consumer
/// that reads DLPack 1.0 or later, the unversioned one otherwise. Never a copy.
template <class T>
py::capsule dlpack_export(const T& value, std::optional<std::pair<int, int>> max_version,
                          std::optional<std::pair<int, int>> dl_device, std::optional<bool> copy) {
  if (dl_device && dl_device->first != kDlCpu) {
    throw py::buffer_error("this value lives in CPU shared memory, not on device (" +
                           std::to_string(dl_device->first) + ", " +
                           std::to_string(dl_device->second) + ")");
  }
  if (copy.value_or(false)) {
    throw py::buffer_error(
        "__dlpack__ exports the pool memory itself; copy it with numpy.array(value)");
  }
  if (max_version && max_version->first >= static_cast<int>(kDlpackVersion.major)) {
    return to_dlpack<DLManagedTensorVersioned>(value);
  }
  return to_dlpack<DLManagedTensor>(value);
}

// ---- from_numpy -------------------------------------------------------------------------------

std::string text_of(const py::handle& object) { return py::str(object).cast<std::string>(); }

msg::TensorDtype dtype_of(const py::dtype& dtype) {
  const char kind = dtype.kind();
  const auto size = dtype.itemsize();
  if (kind == 'f' && size == 4) return msg::TensorDtype::F32;
  if (kind == 'f' && size == 8) return msg::TensorDtype::F64;
  if (kind == 'f' && size == 2) return msg::TensorDtype::F16;
  if (kind == 'u' && size == 1) return msg::TensorDtype::U8;
  if (kind == 'u' && size == 2) return msg::TensorDtype::U16;
  if (kind == 'u' && size == 4) return msg::TensorDtype::U32;
  if (kind == 'u' && size == 8) return msg::TensorDtype::U64;
  if (kind == 'i' && size == 1) return msg::TensorDtype::I8;
  if (kind == 'i' && size == 2) return msg::TensorDtype::I16;
  if (kind == 'i' && size == 4) return msg::TensorDtype::I32;
  if (kind == 'i' && size == 8) return msg::TensorDtype::I64;
  throw Error("arrays of " + text_of(dtype) + " have no TensorDtype");
}

/// `object` as a C-contiguous array (a copy only when it is not already one).
py::array contiguous(const py::object& object) {
  py::array array = py::array::ensure(object, py::array::c_style);
  if (!array) {
    throw py::error_already_set();
  }
  return array;
}

std::span<const std::uint8_t> bytes_of(const py::array& array) {
  return {static_cast<const std::uint8_t*>(array.data()), static_cast<std::size_t>(array.nbytes())};
}

ImageEncoding encoding_for(const py::array& array) {
  const msg::TensorDtype dtype = dtype_of(array.dtype());
  const py::ssize_t channels = array.ndim() == 3 ? array.shape(2) : 1;
  if (array.ndim() == 2 || array.ndim() == 3) {
    if (dtype == msg::TensorDtype::U8 && channels == 1) return ImageEncoding::Mono8;
    if (dtype == msg::TensorDtype::U8 && channels == 3) return ImageEncoding::Rgb8;
    if (dtype == msg::TensorDtype::U8 && channels == 4) return ImageEncoding::Rgba8;
    if (dtype == msg::TensorDtype::U16 && channels == 1) return ImageEncoding::Mono16;
    if (dtype == msg::TensorDtype::F32 && channels == 1) return ImageEncoding::Mono32F;
    if (dtype == msg::TensorDtype::F32 && channels == 3) return ImageEncoding::Rgb32F;
  }
  throw Error(
      "Image.from_numpy: no encoding for an array of shape " +
      text_of(py::cast(std::vector<py::ssize_t>(array.shape(), array.shape() + array.ndim()))) +
      " and dtype " + text_of(array.dtype()) +
      " (pass encoding=, or use (h, w) / (h, w, 3|4) uint8, uint16 or float32)");
}

Image image_from_numpy(const py::object& object, std::optional<ImageEncoding> encoding,
                       std::optional<TensorPool> pool) {
  const py::array array = contiguous(object);
  const ImageEncoding chosen = encoding ? *encoding : encoding_for(array);
  if (array.ndim() < 2) {
    throw Error("Image.from_numpy: an image array has shape (height, width[, channels])");
  }
  Image image = Image::make(static_cast<std::uint32_t>(array.shape(0)),
                            static_cast<std::uint32_t>(array.shape(1)), chosen,
                            pool ? *pool : default_pool());
  image.copy_from(bytes_of(array));
  return image;
}

DepthImage depth_from_numpy(const py::object& object, std::optional<TensorPool> pool) {
  const py::array array = contiguous(object);
  if (array.ndim() != 2) {
    throw Error("DepthImage.from_numpy: a depth array has shape (height, width)");
  }
  const msg::TensorDtype dtype = dtype_of(array.dtype());
  if (dtype != msg::TensorDtype::F32 && dtype != msg::TensorDtype::U16) {
    throw Error("DepthImage.from_numpy: float32 (metres) or uint16 (millimetres), not " +
                text_of(array.dtype()));
  }
  const auto height = static_cast<std::uint32_t>(array.shape(0));
  const auto width = static_cast<std::uint32_t>(array.shape(1));
  const TensorPool& from = pool ? *pool : default_pool();
  DepthImage depth = dtype == msg::TensorDtype::F32 ? DepthImage::meters(height, width, from)
                                                    : DepthImage::millimeters(height, width, from);
  depth.copy_from(bytes_of(array));
  return depth;
}

PointCloud cloud_from_numpy(const py::object& object, std::optional<TensorPool> pool) {
  const py::array array = contiguous(object);
  if (array.ndim() != 2) {
    throw Error("PointCloud.from_numpy: a cloud array has shape (points, fields)");
  }
  PointCloud cloud = PointCloud::make(static_cast<std::uint64_t>(array.shape(0)),
                                      static_cast<std::uint32_t>(array.shape(1)),
                                      dtype_of(array.dtype()), pool ? *pool : default_pool());
  cloud.copy_from(bytes_of(array));
  return cloud;
}

/// PointCloud.from_xyz / from_xyzi / from_xyzrgb: `points` is anything numpy reads as
/// (points, Fields) numbers (an array of any float or integer dtype, a list of tuples); the values
/// are converted to float32 as the C++ constructors take them.
template <std::size_t Fields>
PointCloud cloud_from_points(const py::object& points, std::optional<TensorPool> pool,
                             const char* name) {
  // The constructor, not ensure(): it keeps numpy's error (ValueError for non-numbers).
  const py::array_t<float, py::array::c_style | py::array::forcecast> array(points);
  const bool no_points = array.size() == 0 && array.ndim() == 1;  // [] from an empty list
  if (!no_points && (array.ndim() != 2 || array.shape(1) != static_cast<py::ssize_t>(Fields))) {
    throw Error(
        std::string("PointCloud.") + name + ": points have shape (n, " + std::to_string(Fields) +
        "), not " +
        text_of(py::cast(std::vector<py::ssize_t>(array.shape(), array.shape() + array.ndim()))));
  }
  // std::array<float, N> holds exactly N floats, so a C-contiguous (n, N) array is n of them.
  const std::span<const std::array<float, Fields>> span(
      reinterpret_cast<const std::array<float, Fields>*>(array.data()),
      no_points ? 0 : static_cast<std::size_t>(array.shape(0)));
  const TensorPool& from = pool ? *pool : default_pool();
  if constexpr (Fields == 3) return PointCloud::from_xyz(span, from);
  if constexpr (Fields == 4) return PointCloud::from_xyzi(span, from);
  if constexpr (Fields == 6) return PointCloud::from_xyzrgb(span, from);
}

/// A new (n, 3) float32 array of the cloud's XYZ, or None when the cloud is not float32 with at
/// least three fields (C++'s nullopt).
py::object extract_xyz(const PointCloud& cloud) {
  const auto xyz = cloud.extract_xyz();
  if (!xyz) return py::none();
  py::array_t<float> array({static_cast<py::ssize_t>(xyz->size()), py::ssize_t{3}});
  if (!xyz->empty()) {
    std::memcpy(array.mutable_data(), xyz->data(), xyz->size() * sizeof((*xyz)[0]));
  }
  return array;
}

Tensor tensor_from_numpy(const py::object& object, std::optional<TensorPool> pool) {
  const py::array array = contiguous(object);
  std::vector<std::uint64_t> shape(array.shape(), array.shape() + array.ndim());
  Tensor tensor = Tensor::make(shape, dtype_of(array.dtype()), pool ? *pool : default_pool());
  tensor.copy_from(bytes_of(array));
  return tensor;
}

// ---- Shared members ------------------------------------------------------------------------

template <class T, class Class>
void bind_pool_backed(Class& cls) {
  // The type name a node declares for its topics (publishers() / subscribers()), as C++ does.
  cls.attr("type_name") = std::string(TypeInfo<T>::name);
  // Lambdas, not member pointers: those members belong to the (unbound) base class.
  cls.def_property_readonly(
         "writable", [](const T& value) { return value.writable(); },
         "True for a value this process made, False for a received one.")
      .def_property(
          "frame_id", [](const T& value) { return std::string(value.frame_id()); },
          [](T& value, const std::string& frame) { value.set_frame_id(frame); })
      .def_property(
          "timestamp_ns", [](const T& value) { return value.timestamp_ns(); },
          [](T& value, std::uint64_t timestamp) { value.set_timestamp_ns(timestamp); })
      .def_property_readonly("nbytes", [](const T& value) { return value.size(); })
      .def_property_readonly(
          "data_address",
          [](const T& value) { return reinterpret_cast<std::uintptr_t>(value.data().data()); },
          "Address of the data in this process (inside the pool's mapping).")
      .def_property_readonly("pool", [](const T& value) { return value.pool(); })
      .def_property_readonly("block",
                             [](const T& value) {
                               const msg::PoolBlock& block = value.block();
                               return py::make_tuple(block.pool_id, block.index, block.generation);
                             })
      .def(
          "data",
          [](const T& value) {
            return py::bytes(reinterpret_cast<const char*>(value.data().data()),
                             value.data().size());
          },
          "A copy of the bytes (numpy.asarray(value) is the zero-copy view).")
      .def(
          "copy_from",
          [](T& value, const py::buffer& source) {
            const py::buffer_info info = source.request();
            value.copy_from(
                std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(info.ptr),
                                              static_cast<std::size_t>(info.size * info.itemsize)));
            return &value;
          },
          py::return_value_policy::reference)
      .def("log_summary", &T::log_summary)
      .def("__repr__", &T::log_summary)
      .def(
          "__dlpack__",
          [](const T& value, const py::object& /*stream*/,
             std::optional<std::pair<int, int>> max_version,
             std::optional<std::pair<int, int>> dl_device, std::optional<bool> copy) {
            return dlpack_export(value, max_version, dl_device, copy);
          },
          py::kw_only(), py::arg("stream") = py::none(), py::arg("max_version") = py::none(),
          py::arg("dl_device") = py::none(), py::arg("copy") = py::none())
      .def("__dlpack_device__", [](const T&) { return py::make_tuple(kDlCpu, 0); });
}

template <class T>
void bind_pool_topic(py::module_& m, const char* name) {
  py::class_<Topic<T>>(m, name,
                       "A topic of a pool-backed type: the descriptor goes, the data stays.")
      .def(py::init([](const std::string& topic, std::size_t capacity, const std::string& space) {
             TopicOptions options = pool_topic_options();
             options.capacity = capacity;
             options.namespace_name = space;
             return std::make_unique<Topic<T>>(topic, options);
           }),
           py::arg("name"), py::arg("capacity") = 4, py::arg("namespace") = "")
      .def_property_readonly("name", &Topic<T>::name)
      .def_property_readonly("capacity", &Topic<T>::capacity)
      .def("send", &Topic<T>::send, py::arg("value"))
      .def("try_recv", &Topic<T>::try_recv)
      .def(
          "recv",
          [](Topic<T>& topic, double timeout) {
            const auto wait = std::chrono::duration_cast<std::chrono::nanoseconds>(
                std::chrono::duration<double>(timeout));
            std::optional<T> value;
            {
              py::gil_scoped_release release;
              value = topic.recv(wait);
            }
            return value;
          },
          py::arg("timeout"))
      .def("read_latest", &Topic<T>::read_latest)
      .def("has_msg", &Topic<T>::has_msg)
      .def("lost", &Topic<T>::lost)
      .def("refused", &Topic<T>::refused);
}

}  // namespace

void bind_pool(py::module_& m) {
  py::enum_<PoolExhaustion>(m, "PoolExhaustion")
      .value("Fail", PoolExhaustion::Fail)
      .value("DropOldest", PoolExhaustion::DropOldest);

  py::class_<TensorPool>(m, "TensorPool", "A shared-memory pool of blocks (horus::TensorPool).")
      .def_static(
          "open",
          [](const std::string& name, std::size_t block_size, std::size_t block_count,
             PoolExhaustion on_exhaustion, unsigned mode, const std::string& space) {
            TensorPoolOptions options;
            options.block_size = block_size;
            options.block_count = block_count;
            options.on_exhaustion = on_exhaustion;
            options.mode = mode;
            options.namespace_name = space;
            return TensorPool::open(name, options);
          },
          py::arg("name") = "default", py::arg("block_size") = TensorPoolOptions{}.block_size,
          py::arg("block_count") = TensorPoolOptions{}.block_count,
          py::arg("on_exhaustion") = PoolExhaustion::Fail, py::arg("mode") = 0600,
          py::arg("namespace") = "")
      .def_static("default", &default_pool)
      .def_property_readonly("name", &TensorPool::name)
      .def_property_readonly("id", &TensorPool::id)
      .def_property_readonly("block_size", &TensorPool::block_size)
      .def_property_readonly("block_count", &TensorPool::block_count)
      .def_property("on_exhaustion", &TensorPool::on_exhaustion, &TensorPool::set_on_exhaustion)
      .def("stats",
           [](const TensorPool& pool) {
             const TensorPoolStats stats = pool.stats();
             py::dict out;
             out["block_size"] = stats.block_size;
             out["block_count"] = stats.block_count;
             out["blocks_in_use"] = stats.blocks_in_use;
             out["allocations"] = stats.allocations;
             out["exhausted"] = stats.exhausted;
             out["dropped"] = stats.dropped;
             out["refused"] = stats.refused;
             out["reclaimed"] = stats.reclaimed;
             return out;
           })
      .def(
          "references",
          [](const TensorPool& pool, const py::tuple& block) {
            return pool.references(msg::PoolBlock{block[0].cast<std::uint64_t>(),
                                                  block[1].cast<std::uint32_t>(),
                                                  block[2].cast<std::uint32_t>()});
          },
          py::arg("block"), "References on a block given as a value's .block tuple.")
      .def(
          "contains",
          [](const TensorPool& pool, std::uintptr_t address) {
            return pool.contains(reinterpret_cast<const void*>(address));
          },
          py::arg("address"))
      .def("reclaim", &TensorPool::reclaim);

  py::enum_<ImageEncoding>(m, "ImageEncoding")
      .value("Mono8", ImageEncoding::Mono8)
      .value("Mono16", ImageEncoding::Mono16)
      .value("Rgb8", ImageEncoding::Rgb8)
      .value("Bgr8", ImageEncoding::Bgr8)
      .value("Rgba8", ImageEncoding::Rgba8)
      .value("Bgra8", ImageEncoding::Bgra8)
      .value("Yuv422", ImageEncoding::Yuv422)
      .value("Mono32F", ImageEncoding::Mono32F)
      .value("Rgb32F", ImageEncoding::Rgb32F)
      .value("BayerRggb8", ImageEncoding::BayerRggb8)
      .value("Depth16", ImageEncoding::Depth16);
  py::enum_<msg::TensorDtype>(m, "TensorDtype")
      .value("F32", msg::TensorDtype::F32)
      .value("F64", msg::TensorDtype::F64)
      .value("U8", msg::TensorDtype::U8)
      .value("U16", msg::TensorDtype::U16)
      .value("I16", msg::TensorDtype::I16)
      .value("I32", msg::TensorDtype::I32)
      .value("I8", msg::TensorDtype::I8)
      .value("U32", msg::TensorDtype::U32)
      .value("I64", msg::TensorDtype::I64)
      .value("U64", msg::TensorDtype::U64)
      .value("F16", msg::TensorDtype::F16);

  py::class_<Image> image(m, "Image", py::buffer_protocol());
  image
      .def(py::init([](std::uint32_t height, std::uint32_t width, ImageEncoding encoding,
                       std::optional<TensorPool> pool) {
             return Image::make(height, width, encoding, pool ? *pool : default_pool());
           }),
           py::arg("height"), py::arg("width"), py::arg("encoding"), py::arg("pool") = py::none())
      .def_static("from_numpy", &image_from_numpy, py::arg("array"),
                  py::arg("encoding") = py::none(), py::arg("pool") = py::none())
      .def_buffer([](Image& value) { return buffer_of(value); })
      .def_property_readonly("width", &Image::width)
      .def_property_readonly("height", &Image::height)
      .def_property_readonly("encoding", &Image::encoding)
      .def_property_readonly("channels", &Image::channels)
      .def_property_readonly("step", &Image::step)
      .def("pixel",
           [](const Image& value, std::uint32_t x, std::uint32_t y) -> py::object {
             const auto pixel = value.pixel(x, y);
             if (!pixel) return py::none();
             return py::bytes(reinterpret_cast<const char*>(pixel->data()), pixel->size());
           })
      .def(
          "set_pixel",
          [](Image& value, std::uint32_t x, std::uint32_t y, const py::bytes& pixel) {
            const std::string bytes = pixel;
            value.set_pixel(x, y,
                            std::span<const std::uint8_t>(
                                reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
            return &value;
          },
          py::return_value_policy::reference)
      .def(
          "fill",
          [](Image& value, int byte) {
            value.fill(static_cast<std::uint8_t>(byte));
            return &value;
          },
          py::return_value_policy::reference)
      .def("roi",
           [](const Image& value, std::uint32_t x, std::uint32_t y, std::uint32_t w,
              std::uint32_t h) -> py::object {
             const auto region = value.roi(x, y, w, h);
             if (!region) return py::none();
             return py::bytes(reinterpret_cast<const char*>(region->data()), region->size());
           });
  bind_pool_backed<Image>(image);

  py::class_<DepthImage> depth(m, "DepthImage", py::buffer_protocol());
  depth
      .def_static(
          "meters",
          [](std::uint32_t height, std::uint32_t width, std::optional<TensorPool> pool) {
            return DepthImage::meters(height, width, pool ? *pool : default_pool());
          },
          py::arg("height"), py::arg("width"), py::arg("pool") = py::none())
      .def_static(
          "millimeters",
          [](std::uint32_t height, std::uint32_t width, std::optional<TensorPool> pool) {
            return DepthImage::millimeters(height, width, pool ? *pool : default_pool());
          },
          py::arg("height"), py::arg("width"), py::arg("pool") = py::none())
      .def_static("from_numpy", &depth_from_numpy, py::arg("array"), py::arg("pool") = py::none())
      .def_buffer([](DepthImage& value) { return buffer_of(value); })
      .def_property_readonly("width", &DepthImage::width)
      .def_property_readonly("height", &DepthImage::height)
      .def_property_readonly("dtype", &DepthImage::dtype)
      .def_property_readonly("depth_scale", &DepthImage::depth_scale)
      .def("is_meters", &DepthImage::is_meters)
      .def("is_millimeters", &DepthImage::is_millimeters)
      .def("get_depth", &DepthImage::get_depth)
      .def("set_depth", &DepthImage::set_depth, py::return_value_policy::reference)
      .def("get_depth_u16", &DepthImage::get_depth_u16)
      .def("depth_statistics", [](const DepthImage& value) {
        const DepthStatistics stats = value.depth_statistics();
        return py::make_tuple(stats.min, stats.max, stats.mean);
      });
  bind_pool_backed<DepthImage>(depth);

  py::class_<PointCloud> cloud(m, "PointCloud", py::buffer_protocol());
  cloud.def_static("from_numpy", &cloud_from_numpy, py::arg("array"), py::arg("pool") = py::none())
      .def_static(
          "from_xyz",
          [](const py::object& points, std::optional<TensorPool> pool) {
            return cloud_from_points<3>(points, std::move(pool), "from_xyz");
          },
          py::arg("points"), py::arg("pool") = py::none())
      .def_static(
          "from_xyzi",
          [](const py::object& points, std::optional<TensorPool> pool) {
            return cloud_from_points<4>(points, std::move(pool), "from_xyzi");
          },
          py::arg("points"), py::arg("pool") = py::none())
      .def_static(
          "from_xyzrgb",
          [](const py::object& points, std::optional<TensorPool> pool) {
            return cloud_from_points<6>(points, std::move(pool), "from_xyzrgb");
          },
          py::arg("points"), py::arg("pool") = py::none())
      .def("extract_xyz", &extract_xyz)
      .def_buffer([](PointCloud& value) { return buffer_of(value); })
      .def_property_readonly("point_count", &PointCloud::point_count)
      .def_property_readonly("fields_per_point", &PointCloud::fields_per_point)
      .def_property_readonly("dtype", &PointCloud::dtype)
      .def("is_xyz", &PointCloud::is_xyz)
      .def("has_intensity", &PointCloud::has_intensity)
      .def("has_color", &PointCloud::has_color)
      .def("point_at", [](const PointCloud& value, std::uint64_t index) -> py::object {
        const auto point = value.point_at(index);
        if (!point) return py::none();
        return py::bytes(reinterpret_cast<const char*>(point->data()), point->size());
      });
  bind_pool_backed<PointCloud>(cloud);

  py::class_<Tensor> tensor(m, "Tensor", py::buffer_protocol());
  tensor
      .def(py::init([](const std::vector<std::uint64_t>& shape, msg::TensorDtype dtype,
                       std::optional<TensorPool> pool) {
             return Tensor::make(shape, dtype, pool ? *pool : default_pool());
           }),
           py::arg("shape"), py::arg("dtype"), py::arg("pool") = py::none())
      .def_static("from_numpy", &tensor_from_numpy, py::arg("array"), py::arg("pool") = py::none())
      .def_buffer([](Tensor& value) { return buffer_of(value); })
      .def_property_readonly("shape",
                             [](const Tensor& value) {
                               return std::vector<std::uint64_t>(value.shape().begin(),
                                                                 value.shape().end());
                             })
      .def_property_readonly("strides",
                             [](const Tensor& value) {
                               return std::vector<std::uint64_t>(value.strides().begin(),
                                                                 value.strides().end());
                             })
      .def_property_readonly("dtype", &Tensor::dtype)
      .def_property_readonly("ndim", &Tensor::ndim);
  bind_pool_backed<Tensor>(tensor);

  m.def("remove_pools", &remove_pools, py::arg("namespace") = "",
        "Removes every pool file of a namespace (empty: the current one); for tests and tools.");
  m.def("clean_pools", &clean_pools, py::arg("namespace") = "",
        "Removes the pool files of a namespace that no live process maps; returns how many.");

  bind_pool_topic<Image>(m, "ImageTopic");
  bind_pool_topic<DepthImage>(m, "DepthImageTopic");
  bind_pool_topic<PointCloud>(m, "PointCloudTopic");
  bind_pool_topic<Tensor>(m, "TensorTopic");
}

}  // namespace horus::python
