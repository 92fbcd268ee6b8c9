// The type descriptions (docs/type-description.md) of the types the service layer defines itself:
// the request and response frames of a payload, and the registration record. Built at run time
// from the payload's description (runtime/src/service/frame_description.cpp), the first time
// each is read, and carried as generated types carry theirs: TypeInfo<T>::description, the
// TypeIdentity of a raw service's frames, the topic segments.
#pragma once

#include <string>
#include <string_view>

namespace horus::detail {

/// "horus.ServiceRequest<pkg.X>" / "horus.ServiceResponse<pkg.X>".
std::string service_frame_name(std::string_view payload_name, bool response);
/// The canonical schema text of a frame: its own block, then the payload's schema text.
std::string service_frame_schema(std::string_view payload_name, std::string_view payload_schema,
                                 bool response, bool pod);
/// The description of the request (`response` false) or response frames of the payload
/// `payload_name` whose carried description is `payload_description`. Throws
/// TypeDescriptionError for bytes that are not a description of that payload (none included).
std::string service_frame_description(std::string_view payload_name,
                                      std::string_view payload_description, bool response);
/// The description of horus.ServiceRegistration.
std::string service_registration_description();

/// TypeInfo<T>::description of such a type: read as a std::string_view, as a generated type's,
/// built by `Build` the first time.
template <std::string (*Build)()>
struct BuiltDescription {
  operator std::string_view() const {
    static const std::string bytes = Build();
    return bytes;
  }
};

}  // namespace horus::detail
