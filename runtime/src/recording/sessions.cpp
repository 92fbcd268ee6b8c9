// Where session files live and what they are called: $HORUS_RECORDINGS (default
// ~/.local/share/horus/recordings), session_YYYY_MM_DD_HHMMSS.mcap in local time.
#include <algorithm>
#include <cstdlib>
#include <ctime>
#include <system_error>

#include "horus/error.hpp"
#include "horus/recording.hpp"

namespace horus {
namespace {

constexpr std::string_view kExtension = ".mcap";

}  // namespace

std::filesystem::path recordings_directory() {
  // Read when a recording starts; programs set the variable before they start threads.
  const char* configured = std::getenv("HORUS_RECORDINGS");  // NOLINT(concurrency-mt-unsafe)
  std::filesystem::path directory;
  if (configured != nullptr && *configured != '\0') {
    directory = configured;
  } else {
    const char* home = std::getenv("HOME");  // NOLINT(concurrency-mt-unsafe)
    if (home == nullptr || *home == '\0') {
      throw Error("cannot place recordings: neither HORUS_RECORDINGS nor HOME is set");
    }
    directory = std::filesystem::path(home) / ".local/share/horus/recordings";
  }
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) {
    throw Error("cannot create the recordings folder " + directory.string() + ": " +
                error.message());
  }
  return directory;
}

std::filesystem::path new_recording_path() {
  const std::filesystem::path directory = recordings_directory();
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  localtime_r(&now, &local);
  char stem[64];
  std::strftime(stem, sizeof stem, "session_%Y_%m_%d_%H%M%S", &local);
  std::filesystem::path path = directory / (std::string(stem) + std::string(kExtension));
  for (int suffix = 2; std::filesystem::exists(path); ++suffix) {
    path = directory / (std::string(stem) + "_" + std::to_string(suffix) + std::string(kExtension));
  }
  return path;
}

std::vector<std::string> list_recordings() {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(recordings_directory())) {
    if (entry.is_regular_file() && entry.path().extension() == kExtension) {
      names.push_back(entry.path().stem().string());
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

bool delete_recording(std::string_view name) {
  std::string file(name);
  if (file.empty() || file == "." || file == ".." || file.find('/') != std::string::npos ||
      file.find('\0') != std::string::npos) {
    throw Error("delete_recording: '" + file + "' is not a recording name (a file name in " +
                recordings_directory().string() + ")");
  }
  if (!file.ends_with(kExtension)) file += kExtension;
  std::error_code error;
  const bool removed = std::filesystem::remove(recordings_directory() / file, error);
  if (error) {
    throw Error("cannot delete recording " + (recordings_directory() / file).string() + ": " +
                error.message());
  }
  return removed;
}

}  // namespace horus
