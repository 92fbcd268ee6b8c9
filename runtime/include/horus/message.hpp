// What every generated message header includes: identity (TypeInfo), string<N>, and the log
// summary rules. Kept small on purpose: <vector>, <optional> and MessagePack come in only with
// the serialized messages that need them (horus/msgpack.hpp), encode/decode with horus/codec.hpp.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "horus/fixed_string.hpp"
#include "horus/log_summary.hpp"
#include "horus/type_info.hpp"
