// horus-remote: a robot's topics reached from afar over Cap'n Proto RPC with mutual TLS
// (bridges/remote/README.md, docs/remote.md); `horus remote serve|connect` runs it.
//
//   horus-remote serve --listen HOST:PORT --certs DIR --name NAME [--allow LINE]...
//                      [--policy FILE] [--insecure] [--namespace NS]
//   horus-remote connect HOST:PORT --certs DIR --name NAME [--server-name NAME]
//                      [--import PATTERN]... [--export PATTERN]... [--params PATTERN]...
//                      [--import-frames PATTERN]... [--export-frames PATTERN]...
//                      [--queue N] [--call-timeout SECONDS] [--insecure]
//                      [--namespace NS]
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <string_view>

#include "horus/topic_registry.hpp"
#include "link.hpp"
#include "remote.hpp"

namespace horus::remote {

namespace {

constexpr unsigned kDefaultQueue = 64;
/// How often the status file (`horus remote status`) is written.
constexpr auto kStatusInterval = 1 * kj::SECONDS;

kj::AsyncIoContext set_up_async_io() {
  // Before any thread starts: the signals stay blocked in every thread but kj's event loop.
  kj::UnixEventPort::captureSignal(SIGINT);
  kj::UnixEventPort::captureSignal(SIGTERM);
  std::signal(SIGPIPE, SIG_IGN);
  return kj::setupAsyncIo();
}

int usage(std::FILE* out, int status) {
  std::fprintf(
      out,
      "usage: horus-remote serve --listen HOST:PORT --certs DIR --name NAME\n"
      "                          [--allow 'PEER read|write|call|param PATTERN']...\n"
      "                          [--allow 'PEER read|write @frames/CHILD']...\n"
      "                          [--policy FILE]\n"
      "       horus-remote connect HOST:PORT --certs DIR --name NAME [--server-name NAME]\n"
      "                          [--import PATTERN]... [--export PATTERN]... [--queue N]\n"
      "                          [--params NODE.PARAMETER]... [--call-timeout SECONDS]\n"
      "                          [--import-frames CHILD]... [--export-frames CHILD]...\n"
      "  both:  [--namespace NS] [--insecure (plain TCP: no authentication, no encryption)]\n"
      "serve: serves the namespace to peers with a certificate of DIR's CA, each limited to\n"
      "       what the policy lines allow its certificate name (globs; the rest is denied).\n"
      "connect: mirrors the robot's topics matching --import here, sends local topics\n"
      "       matching --export to the robot; reconnects with backoff. --params: mirrors the\n"
      "       robot's parameters matching it (globs on NODE.PARAMETER) here while connected.\n"
      "       --import-frames: sets the robot's coordinate frames whose child matches it here;\n"
      "       --export-frames: has the robot set the local frames matching it (globs).\n"
      "       --server-name: the name in the robot's certificate (default: HOST). --queue:\n"
      "       messages a stream may fall behind before the oldest are dropped (default %u).\n"
      "       --call-timeout: how long the robot waits for its server to answer a call\n"
      "       (default 10, at most %u).\n",
      kDefaultQueue, kLongestCallMs / 1000);
  return status;
}

[[noreturn]] void usage_error(const std::string& text) {
  std::fprintf(stderr, "horus-remote: %s\n", text.c_str());
  std::exit(usage(stderr, 2));
}

}  // namespace

EventLoop::EventLoop() : io(set_up_async_io()) { use_event_port(io.unixEventPort); }

void EventLoop::run_until_stopped(kj::Promise<void> work, const std::string& namespace_name,
                                  const char* role) {
  const std::string path = status_path(namespace_name);
  KJ_DEFER(std::remove(path.c_str()));
  kj::Function<kj::Promise<void>()> report = [&]() -> kj::Promise<void> {
    write_status(path, role);
    return io.provider->getTimer().afterDelay(kStatusInterval).then([&] { return report(); });
  };
  kj::Promise<void> stopped = io.unixEventPort.onSignal(SIGINT).ignoreResult().exclusiveJoin(
      io.unixEventPort.onSignal(SIGTERM).ignoreResult());
  work.exclusiveJoin(kj::mv(stopped)).exclusiveJoin(report()).wait(io.waitScope);
}

namespace {

int run(int argc, char** argv) {
  if (argc < 2) return usage(stderr, 2);
  const std::string_view command = argv[1];
  if (command == "-h" || command == "--help") return usage(stdout, 0);
  if (command != "serve" && command != "connect")
    usage_error("no command '" + std::string(command) + "'");
  ServeOptions serving;
  ConnectOptions connecting;
  connecting.queue = kDefaultQueue;
  std::string namespace_name;
  std::string certs;
  std::string name;
  bool insecure = false;
  for (int i = 2; i < argc; ++i) {
    const std::string_view arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage_error(std::string(arg) + " needs a value");
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") {
      return usage(stdout, 0);
    } else if (arg == "--namespace" || arg == "-n") {
      namespace_name = value();
    } else if (arg == "--certs") {
      certs = value();
    } else if (arg == "--name") {
      name = value();
    } else if (arg == "--insecure") {
      insecure = true;
    } else if (command == "serve" && arg == "--listen") {
      serving.listen = value();
    } else if (command == "serve" && arg == "--allow") {
      try {
        serving.policy.add(value(), "--allow");
      } catch (const std::invalid_argument& e) {
        usage_error(e.what());
      }
    } else if (command == "serve" && arg == "--policy") {
      serving.policy.load(value());
    } else if (command == "connect" && arg == "--server-name") {
      connecting.server_name = value();
    } else if (command == "connect" && arg == "--import") {
      connecting.imports.push_back(value());
    } else if (command == "connect" && arg == "--params") {
      connecting.params.push_back(value());
    } else if (command == "connect" && arg == "--import-frames") {
      connecting.import_frames.push_back(value());
    } else if (command == "connect" && arg == "--export-frames") {
      connecting.export_frames.push_back(value());
    } else if (command == "connect" && arg == "--export") {
      connecting.exports.push_back(value());
    } else if (command == "connect" && arg == "--queue") {
      const std::string text = value();
      char* end = nullptr;
      const unsigned long queue = std::strtoul(text.c_str(), &end, 10);
      if (end == text.c_str() || *end != '\0' || queue == 0 || queue > 1024) {
        usage_error("--queue needs a number of messages from 1 to 1024, not '" + text + "'");
      }
      connecting.queue = static_cast<unsigned>(queue);
    } else if (command == "connect" && arg == "--call-timeout") {
      const std::string text = value();
      char* end = nullptr;
      const double seconds = std::strtod(text.c_str(), &end);
      if (end == text.c_str() || *end != '\0' || !(seconds >= 0.001) ||
          !(seconds <= kLongestCallMs / 1000.0)) {
        usage_error("--call-timeout needs a number of seconds from 0.001 to " +
                    std::to_string(kLongestCallMs / 1000) + ", not '" + text + "'");
      }
      connecting.call_timeout = std::chrono::milliseconds(std::llround(seconds * 1000));
    } else if (command == "connect" && connecting.address.empty() && !arg.starts_with("-")) {
      connecting.address = arg;
    } else {
      usage_error("unknown argument " + std::string(arg));
    }
  }
  if (command == "serve" && serving.listen.empty()) usage_error("serve needs --listen HOST:PORT");
  if (command == "connect" && connecting.address.empty()) {
    usage_error("connect needs the robot's HOST:PORT");
  }
  if (!insecure && (certs.empty() || name.empty())) {
    usage_error("--certs DIR and --name NAME are needed (or --insecure)");
  }
  if (namespace_name.empty()) namespace_name = current_namespace();
  if (command == "serve") {
    serving.certs = certs;
    serving.name = name;
    serving.namespace_name = namespace_name;
    serving.insecure = insecure;
    return serve(serving);
  }
  if (connecting.server_name.empty()) {
    connecting.server_name = connecting.address.substr(0, connecting.address.rfind(':'));
  }
  connecting.certs = certs;
  connecting.name = name;
  connecting.namespace_name = namespace_name;
  connecting.insecure = insecure;
  return connect(connecting);
}

}  // namespace

}  // namespace horus::remote

int main(int argc, char** argv) {
  // Frames of pool-backed topics cross with their data (link.hpp: Forwarder, TopicSink).
  horus::enable_pool_frames();
  try {
    return horus::remote::run(argc, argv);
  } catch (const kj::Exception& e) {
    horus::remote::say("%s", e.getDescription().cStr());
  } catch (const std::exception& e) {
    horus::remote::say("%s", e.what());
  }
  return 1;
}
