// The built-in page (bridges/view/page/), compiled into the program (cmake/embed_page.cmake):
// served at the HTTP paths of the port the WebSocket listens on, "/" being "/index.html".
#pragma once

#include <span>
#include <string_view>

namespace horus::view {

struct PageFile {
  /// "/index.html".
  std::string_view path;
  std::string_view content_type;
  std::string_view content;
};

std::span<const PageFile> page_files();

}  // namespace horus::view
