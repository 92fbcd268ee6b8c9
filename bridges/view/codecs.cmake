# horus::view_codecs: how the live view shows each topic to a Foxglove viewer (codecs.hpp): the
# channel's schema and each frame as a JSON or protobuf payload, built from the topic's type
# description. No transport, no protobuf library: the few protobuf messages are written by hand.
# A viewer's JSON is read by Cap'n Proto's parser (capnp-json), as the view's protocol reads it.
add_library(horus_view_codecs STATIC
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs_json.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs_json_value.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs_message_value.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs_foxglove_json.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/codecs_protobuf.cpp)
add_library(horus::view_codecs ALIAS horus_view_codecs)
target_include_directories(horus_view_codecs PUBLIC
  $<BUILD_INTERFACE:${CMAKE_CURRENT_LIST_DIR}/include> $<INSTALL_INTERFACE:include>)
target_link_libraries(horus_view_codecs PUBLIC horus::runtime PRIVATE CapnProto::capnp-json)
target_compile_features(horus_view_codecs PUBLIC cxx_std_20)
target_compile_options(horus_view_codecs PRIVATE ${HORUS_WARNINGS})
set_target_properties(horus_view_codecs PROPERTIES POSITION_INDEPENDENT_CODE ON)
