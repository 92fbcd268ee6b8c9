// Prints every type the runtime defines itself (service frames and registration, plain values),
// one JSON object a line: {"name", "fingerprint" (16 hex digits), "schema", "pod", "size",
// "bytes" (a sample value as a topic carries it, hex; POD types only)}. test_record_services.py
// checks that each stored schema gives its fingerprint and decodes those bytes.
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>

#include <horus/detail/service_frame.hpp>
#include <horus/json_string.hpp>
#include <horus/plain_value.hpp>
#include <pyrt_test/add.hpp>
#include <pyrt_test/echo.hpp>

namespace {

/// A POD type with a sample value, or a serialized one (`sample` null: its bytes are the topic's
/// own encoding, which the live session of test_record_services.py decodes).
template <class T>
void print(const T* sample) {
  using Info = horus::TypeInfo<T>;
  std::string bytes;
  if constexpr (std::is_trivially_copyable_v<T>) {
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, sample, sizeof(T));
    char hex[3];
    for (const unsigned char byte : raw) {
      std::snprintf(hex, sizeof hex, "%02x", byte);
      bytes += hex;
    }
  }
  std::printf(
      "{\"name\":%s,\"fingerprint\":\"%016llx\",\"schema\":%s,\"pod\":%s,\"size\":%zu,"
      "\"bytes\":\"%s\"}\n",
      horus::json_string(Info::name).c_str(), static_cast<unsigned long long>(Info::fingerprint),
      horus::json_string(Info::schema).c_str(), Info::is_pod ? "true" : "false", sizeof(T),
      bytes.c_str());
}

template <class T>
void print_plain(T value) {
  print<T>(&value);
}

}  // namespace

int main() {
  using horus::ServiceRegistration;
  using horus::detail::ServiceRequestFrame;
  using horus::detail::ServiceResponseFrame;
  // Zeroed first, so that the padding of the samples is zero, as a topic's slot is.
  ServiceRegistration registration;
  std::memset(static_cast<void*>(&registration), 0, sizeof registration);
  registration.server_instance = (std::uint64_t{1} << 60) + 1;
  registration.fingerprint = pyrt_test::Add::fingerprint();
  registration.request_type.try_assign("pyrt_test.AddRequest");
  registration.response_type.try_assign("pyrt_test.AddResponse");
  registration.server_pid = 4242;
  print(&registration);
  ServiceRequestFrame<pyrt_test::AddRequest> request;
  std::memset(static_cast<void*>(&request), 0, sizeof request);
  request.client_id = 7;
  request.request_id = 8;
  request.reply_to = 1;
  request.payload.a = -4;
  request.payload.b = 5;
  print(&request);
  ServiceResponseFrame<pyrt_test::AddResponse> response;
  std::memset(static_cast<void*>(&response), 0, sizeof response);
  response.client_id = 7;
  response.request_id = 8;
  response.status = horus::detail::kStatusFailed;
  horus::detail::set_error(response, "negative a: -4");
  print(&response);
  print<ServiceRequestFrame<pyrt_test::EchoRequest>>(nullptr);
  print<ServiceResponseFrame<pyrt_test::EchoResponse>>(nullptr);
  print_plain(true);
  print_plain(std::int8_t{-8});
  print_plain(std::int16_t{-16});
  print_plain(std::int32_t{-32});
  print_plain(std::int64_t{-(std::int64_t{1} << 62)});
  print_plain(std::uint8_t{8});
  print_plain(std::uint16_t{16});
  print_plain(std::uint32_t{32});
  print_plain(std::uint64_t{(std::uint64_t{1} << 63) + 1});
  print_plain(1.5F);
  print_plain(-2.25);
  print_plain(std::array<float, 3>{1.0F, 2.0F, 3.0F});
  print_plain(std::array<std::array<std::uint8_t, 4>, 2>{{{1, 2, 3, 4}, {5, 6, 7, 8}}});
  return 0;
}
