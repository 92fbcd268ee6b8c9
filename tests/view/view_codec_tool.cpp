// The live view's codecs driven from files, for test_view_codecs.py, which reads what they write
// with readers that are not ours (jsonschema, python3-protobuf):
//
//   view_codec_tool TOPIC DESCRIPTION OUT [encode FRAME | decode PAYLOAD]...
//
// DESCRIPTION holds a type description (MessagePack, carried form). Writes OUT/channel.json (the
// ChannelSchema's encoding, schema_name, schema_encoding, schema_is_binary), OUT/schema (its
// schema bytes), and for the i-th request (from 0) OUT/<i>.out, or OUT/<i>.error holding the
// CodecError's text.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

#include "horus/json_string.hpp"
#include "horus/type_description.hpp"
#include "horus/view/codecs.hpp"

namespace {

std::vector<std::byte> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto* data = reinterpret_cast<const std::byte*>(text.data());
  return {data, data + text.size()};
}

void write_file(const std::string& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

void write_file(const std::string& path, const std::vector<std::byte>& bytes) {
  write_file(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4 || (argc - 4) % 2 != 0) {
    std::cerr
        << "usage: view_codec_tool TOPIC DESCRIPTION OUT [encode FRAME | decode PAYLOAD]...\n";
    return 2;
  }
  try {
    const std::string topic = argv[1];
    const std::vector<std::byte> description = read_file(argv[2]);
    const std::string out = argv[3];
    horus::TypeIdentity type;
    type.description.assign(reinterpret_cast<const char*>(description.data()), description.size());
    const horus::TypeDescription decoded = horus::TypeDescription::decode(type.description);
    const horus::MessageType& root = decoded.root_message();
    type.name = root.name;
    type.fingerprint = root.fingerprint;
    type.is_pod = root.is_pod;
    type.size = root.size;

    const std::unique_ptr<horus::view::MessageCodec> codec = horus::view::codec_for(type, topic);
    const horus::view::ChannelSchema& schema = codec->schema();
    write_file(out + "/channel.json",
               "{\"encoding\": " + horus::json_string(schema.encoding) +
                   ", \"schema_name\": " + horus::json_string(schema.schema_name) +
                   ", \"schema_encoding\": " + horus::json_string(schema.schema_encoding) +
                   ", \"schema_is_binary\": " + (schema.schema_is_binary ? "true" : "false") +
                   "}\n");
    write_file(out + "/schema", schema.schema);

    std::vector<std::byte> result;
    for (int i = 4, request = 0; i < argc; i += 2, ++request) {
      const std::string action = argv[i];
      const std::vector<std::byte> input = read_file(argv[i + 1]);
      const std::string name = out + "/" + std::to_string(request);
      try {
        if (action == "encode") {
          codec->encode(input, result);
        } else if (action == "decode") {
          codec->decode(input, result);
        } else {
          throw std::runtime_error("unknown request " + action);
        }
        write_file(name + ".out", result);
      } catch (const horus::view::CodecError& error) {
        write_file(name + ".error", std::string_view(error.what()));
      }
    }
  } catch (const std::exception& error) {
    std::cerr << "view_codec_tool: " << error.what() << "\n";
    return 1;
  }
  return 0;
}
