// The generic half of the cross-language tests: for every message type of the test schemas and of
// the standard library (the list comes from horus-gen describe, see type_list.py), decodes the
// bytes Python wrote and writes them back encoded by C++, with the log summary and fingerprint.
// Python (tests/python/test_python_crosslang.py) then requires the very same bytes and text.
//
//   horus_crosslang_echo DIR   reads DIR/<type>.bin, writes DIR/<type>.echo.bin and .echo.txt,
//                              and DIR/fingerprints.echo.txt; a type that fails to decode is
//                              reported on stderr and makes the exit status 1.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <horus/codec.hpp>
#include <horus/msgpack.hpp>

#include "echo_types.hpp"

namespace {

namespace fs = std::filesystem;

template <class T>
bool echo_one(const fs::path& dir, std::string& fingerprints) {
  const std::string name(horus::TypeInfo<T>::name);
  char hex[32];
  std::snprintf(hex, sizeof hex, "0x%016llx",
                static_cast<unsigned long long>(horus::TypeInfo<T>::fingerprint));
  fingerprints += name + " " + hex + "\n";
  std::ifstream in(dir / (name + ".bin"), std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "%s: %s.bin is missing\n", name.c_str(), name.c_str());
    return false;
  }
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  try {
    const T msg = horus::decode<T>(bytes);
    const std::vector<std::uint8_t> again = horus::encode(msg);
    std::ofstream(dir / (name + ".echo.bin"), std::ios::binary)
        .write(reinterpret_cast<const char*>(again.data()),
               static_cast<std::streamsize>(again.size()));
    const std::string summary = msg.log_summary();
    std::ofstream(dir / (name + ".echo.txt"), std::ios::binary)
        .write(summary.data(), static_cast<std::streamsize>(summary.size()));
    return true;
  } catch (const horus::DecodeError& error) {
    std::fprintf(stderr, "%s: C++ cannot decode Python's bytes: %s\n", name.c_str(), error.what());
    return false;
  }
}

template <class... Ts>
int echo_all(TypeList<Ts...>, const fs::path& dir) {
  std::string fingerprints;
  const bool ok = (echo_one<Ts>(dir, fingerprints) & ...);
  std::ofstream(dir / "fingerprints.echo.txt", std::ios::binary) << fingerprints;
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: horus_crosslang_echo DIR\n");
    return 2;
  }
  return echo_all(EchoTypes{}, argv[1]);
}
