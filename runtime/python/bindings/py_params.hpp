// Parameters of Python nodes: a declaration whose type is known only at run time (a schema
// spelling, a generated enum's description), declared through
// Node::declare_param(ParamDeclaration).
#pragma once

#include <pybind11/pybind11.h>

#include <optional>
#include <string>
#include <vector>

#include "horus/params.hpp"

namespace horus::python {

/// The declaration a Python node's declare_param() describes. `spelling` is the schema's ("f32",
/// "[f64; 3]", "String", or a generated enum's name, whose carried type description is
/// `enum_description`); values are MessagePack VALUE bytes. Throws ParamError for an unknown
/// type or a value of another type.
ParamDeclaration python_param_declaration(std::string name, const std::string& spelling,
                                          const std::string& default_value,
                                          std::optional<double> min, std::optional<double> max,
                                          const std::vector<std::string>& choices, std::string unit,
                                          std::string doc, bool read_only,
                                          const std::optional<std::string>& enum_description);

}  // namespace horus::python
