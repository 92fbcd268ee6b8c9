// Telemetry export: a JSON snapshot of node metrics and health to a file or a UDP endpoint; off
// by default; a bad endpoint is refused at construction.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "horus/error.hpp"
#include "horus/literals.hpp"
#include "horus/scheduler.hpp"

using namespace horus::literals;

namespace {

class Sensor : public horus::Node {
 public:
  std::string_view name() const override { return "sensor \"front\""; }
  void tick() override {}
};

std::string error_of(const std::string& endpoint) {
  try {
    horus::Scheduler sched{horus::SchedulerConfig{}.telemetry(endpoint)};
  } catch (const horus::Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Telemetry, IsOffByDefault) { EXPECT_TRUE(horus::SchedulerConfig{}.telemetry().empty()); }

TEST(Telemetry, AFileEndpointHoldsTheLastSnapshot) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("horus_telemetry_" + std::to_string(::getpid()) + ".json");
  {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.name("tele").deterministic(true).tick_rate(100_hz).telemetry(
            "file://" + path.string())};
    sched.add(std::make_shared<Sensor>()).build();
    EXPECT_EQ(sched.run_for(1_s), 0);
  }
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string json = text.str();
  std::filesystem::remove(path);
  EXPECT_EQ(json.rfind("{\"scheduler\":\"tele\",", 0), 0U) << json;
  EXPECT_NE(json.find("\"name\":\"sensor \\\"front\\\"\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"total_ticks\":100,"), std::string::npos) << json;
  EXPECT_NE(json.find("\"health\":\"Healthy\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"state\":\"Stopped\""), std::string::npos) << json;
}

TEST(Telemetry, AUdpEndpointReceivesSnapshots) {
  const int receiver = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(receiver, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(receiver, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  socklen_t size = sizeof(address);
  ::getsockname(receiver, reinterpret_cast<sockaddr*>(&address), &size);
  const std::string endpoint = "udp://127.0.0.1:" + std::to_string(ntohs(address.sin_port));
  {
    horus::Scheduler sched{horus::SchedulerConfig{}
                               .name("udp_tele")
                               .tick_rate(100_hz)
                               .handle_signals(false)
                               .telemetry(endpoint)
                               .telemetry_interval(10_ms)};
    sched.add(std::make_shared<Sensor>()).build();
    sched.run_for(50_ms);
  }
  timeval wait{5, 0};
  ::setsockopt(receiver, SOL_SOCKET, SO_RCVTIMEO, &wait, sizeof(wait));
  char buffer[65536];
  const ssize_t n = ::recv(receiver, buffer, sizeof(buffer), 0);
  ::close(receiver);
  ASSERT_GT(n, 0);
  const std::string json(buffer, static_cast<std::size_t>(n));
  EXPECT_EQ(json.rfind("{\"scheduler\":\"udp_tele\",", 0), 0U) << json;
  EXPECT_NE(json.find("\"nodes\":[{\"name\":\"sensor \\\"front\\\"\""), std::string::npos) << json;
}

TEST(Telemetry, ABadEndpointIsRefused) {
  EXPECT_NE(error_of("http://fleet.example.com").find("expected udp://HOST:PORT or file:///PATH"),
            std::string::npos);
  EXPECT_NE(error_of("udp://127.0.0.1").find("expected udp://HOST:PORT"), std::string::npos);
  EXPECT_NE(error_of("file://relative.json").find("must be absolute"), std::string::npos);
  EXPECT_NE(error_of("udp://no.such.host.invalid:9000").find("telemetry endpoint"),
            std::string::npos);
  try {
    horus::Scheduler sched{
        horus::SchedulerConfig{}.telemetry("udp://127.0.0.1:9").telemetry_interval(0_ms)};
    FAIL() << "expected horus::Error";
  } catch (const horus::Error& e) {
    EXPECT_NE(std::string(e.what()).find("telemetry_interval must be positive"), std::string::npos);
  }
}
