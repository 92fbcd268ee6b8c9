// horus-view: a running namespace served to Foxglove, Lichtblick and the built-in page over the
// Foxglove WebSocket protocol (bridges/view/README.md).
//
//   horus-view serve [--namespace NS] [--listen ADDR] [--port N] [--tls DIR --name NAME]
//                    [--allow 'PEER read|write|call|param PATTERN']... [--policy FILE]...
//                    [--tokens FILE]
//   horus-view status [--namespace NS]
#include <dirent.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>

#include "horus/live_view.hpp"
#include "horus/topic_registry.hpp"

namespace {

/// How often the status file (`horus-view status`) is rewritten.
constexpr int kStatusIntervalSeconds = 1;

int usage(std::FILE* out, int status) {
  std::fprintf(
      out,
      "usage: horus-view serve [--namespace NS] [--listen ADDR] [--port N] [--tls DIR --name "
      "NAME]\n"
      "                        [--allow 'PEER read|write|call|param PATTERN']... [--policy "
      "FILE]...\n"
      "                        [--tokens FILE]\n"
      "       horus-view status [--namespace NS]\n"
      "serve: serves the namespace's topics over the Foxglove WebSocket protocol\n"
      "       (Foxglove, Lichtblick: ws://ADDR:PORT/, wss:// with --tls); prints\n"
      "       'ready ws://ADDR:PORT/' (or wss://) once listening. --port: default 8765, 0: any\n"
      "       free port. --listen: default 127.0.0.1; any address beyond this machine needs\n"
      "       --tls and a policy.\n"
      "       --tls DIR --name NAME: wss:// with `horus remote keygen DIR NAME`'s certificates\n"
      "       (DIR/NAME.crt and .key served; a client may present a certificate of DIR/ca.crt,\n"
      "       and is then the peer its name names).\n"
      "       --allow LINE, --policy FILE: what each peer may do, as horus remote's policy\n"
      "       (globs; the rest is denied). With a policy every client authenticates: by a\n"
      "       client certificate or by ?token=TOKEN in its URL, a token of --tokens FILE\n"
      "       (lines 'PEER TOKEN'; the file must be yours and mode 600). It sees only the\n"
      "       topics it may read and services it may call, and publishes only where it may write.\n"
      "status: the clients of each horus-view serving the namespace, their\n"
      "       subscriptions, messages sent and dropped (JSON, one line per server).\n");
  return status;
}

[[noreturn]] void usage_error(const std::string& text) {
  std::fprintf(stderr, "horus-view: %s\n", text.c_str());
  std::exit(usage(stderr, 2));
}

/// The folder of the status files: $XDG_RUNTIME_DIR/horus-view, else /tmp/horus-view-UID.
std::string status_folder() {
  const char* runtime = std::getenv("XDG_RUNTIME_DIR");
  return runtime != nullptr && *runtime != '\0' ? std::string(runtime) + "/horus-view"
                                                : "/tmp/horus-view-" + std::to_string(::getuid());
}

/// Replaced whole: a reader never sees half of it.
void write_status(const std::string& path, const std::string& text) {
  const std::string partial = path + ".partial";
  if (std::FILE* file = std::fopen(partial.c_str(), "w")) {
    std::fputs(text.c_str(), file);
    std::fclose(file);
    std::rename(partial.c_str(), path.c_str());
  }
}

int serve(horus::LiveViewOptions options) {
  // Before any thread starts: the signals stay blocked in every thread, and this one takes them.
  sigset_t stopping;
  sigemptyset(&stopping);
  sigaddset(&stopping, SIGINT);
  sigaddset(&stopping, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stopping, nullptr);
  signal(SIGPIPE, SIG_IGN);

  horus::LiveView view(options);
  view.start();
  // An IPv6 address goes in brackets in a URL.
  const bool bracketed = options.listen_address.find(':') != std::string::npos;
  std::printf("ready %s://%s%s%s:%u/\n", options.tls_folder.empty() ? "ws" : "wss",
              bracketed ? "[" : "", options.listen_address.c_str(), bracketed ? "]" : "",
              static_cast<unsigned>(view.port()));
  std::fflush(stdout);

  const std::string folder = status_folder();
  ::mkdir(folder.c_str(), 0700);
  const std::string path =
      folder + "/" + options.namespace_name + "." + std::to_string(::getpid()) + ".json";
  const timespec interval{kStatusIntervalSeconds, 0};
  for (;;) {
    write_status(path, view.status_json());
    const int signal_number = sigtimedwait(&stopping, nullptr, &interval);
    if (signal_number == SIGINT || signal_number == SIGTERM) break;
  }
  view.stop();
  std::remove(path.c_str());
  return 0;
}

bool process_alive(long pid) { return pid > 0 && (::kill(pid, 0) == 0 || errno == EPERM); }

int status(const std::string& namespace_name) {
  const std::string folder = status_folder();
  const std::string prefix = namespace_name + ".";
  int shown = 0;
  if (DIR* directory = ::opendir(folder.c_str())) {
    while (const dirent* entry = ::readdir(directory)) {
      const std::string_view name = entry->d_name;
      if (!name.starts_with(prefix) || !name.ends_with(".json")) continue;
      const std::string_view pid_text = name.substr(prefix.size(), name.size() - prefix.size() - 5);
      const long pid = std::strtol(std::string(pid_text).c_str(), nullptr, 10);
      const std::string path = folder + "/" + std::string(name);
      if (!process_alive(pid)) {
        std::remove(path.c_str());  // left by a horus-view that was killed
        continue;
      }
      std::ifstream file(path);
      std::stringstream text;
      text << file.rdbuf();
      std::fputs(text.str().c_str(), stdout);
      ++shown;
    }
    ::closedir(directory);
  }
  if (shown == 0) {
    std::fprintf(stderr, "horus-view: no horus-view serves namespace '%s'\n",
                 namespace_name.c_str());
    return 1;
  }
  return 0;
}

int run(int argc, char** argv) {
  if (argc < 2) return usage(stderr, 2);
  const std::string_view command = argv[1];
  if (command == "-h" || command == "--help") return usage(stdout, 0);
  if (command != "serve" && command != "status") {
    usage_error("no command '" + std::string(command) + "'");
  }
  horus::LiveViewOptions options;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(std::string(arg) + " needs a value");
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") {
      return usage(stdout, 0);
    } else if (arg == "--namespace" || arg == "-n") {
      options.namespace_name = value();
    } else if (command == "serve" && arg == "--listen") {
      options.listen_address = value();
    } else if (command == "serve" && arg == "--port") {
      const std::string text = value();
      char* end = nullptr;
      const unsigned long port = std::strtoul(text.c_str(), &end, 10);
      if (end == text.c_str() || *end != '\0' || port > 65535) {
        usage_error("--port needs a port number from 0 to 65535, not '" + text + "'");
      }
      options.port = static_cast<std::uint16_t>(port);
    } else if (command == "serve" && arg == "--tls") {
      options.tls_folder = value();
    } else if (command == "serve" && arg == "--name") {
      options.tls_name = value();
    } else if (command == "serve" && arg == "--allow") {
      options.policy_lines.push_back(value());
    } else if (command == "serve" && arg == "--policy") {
      options.policy_files.push_back(value());
    } else if (command == "serve" && arg == "--tokens") {
      options.tokens_file = value();
    } else {
      usage_error("unknown argument " + std::string(arg));
    }
  }
  if (options.namespace_name.empty()) options.namespace_name = horus::current_namespace();
  return command == "serve" ? serve(options) : status(options.namespace_name);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
  }
  return 1;
}
