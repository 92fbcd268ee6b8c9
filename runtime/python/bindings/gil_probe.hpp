// A look at the GIL without taking it (gil_probe.cpp).
#pragma once

namespace horus::python {

/// Whether a thread holds the GIL now (a relaxed read: it may change at once).
bool gil_taken() noexcept;

}  // namespace horus::python
