// Whether some thread holds the GIL, read from CPython 3.11's runtime state: the one thing its
// API does not say. Alone in this file because it needs CPython's internal headers.
#define Py_BUILD_CORE 1
#include <Python.h>
// The internal atomics in their GCC-builtin form: their <stdatomic.h> form is C only.
#undef HAVE_STD_ATOMIC
#include <internal/pycore_runtime.h>

#include "gil_probe.hpp"

namespace horus::python {

bool gil_taken() noexcept { return _Py_atomic_load_relaxed(&_PyRuntime.ceval.gil.locked) == 1; }

}  // namespace horus::python
