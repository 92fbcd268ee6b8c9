// The live view's server (bridges/view/): a kj WebSocket client in the test speaks the Foxglove
// WebSocket protocol to a horus::LiveView serving the test's private namespace: the handshake
// with each subprotocol, serverInfo, channels advertised as topics come and go, Message Data
// with the codec's payload, clientPublish, and a client that stops reading.
#include <gtest/gtest.h>
#include <kj/async-io.h>
#include <kj/compat/http.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <deque>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "access.hpp"
#include "horus/codec.hpp"
#include "horus/error.hpp"
#include "horus/live_view.hpp"
#include "horus/msg/cmd_vel.hpp"
#include "horus/msg/compressed_image.hpp"
#include "horus/raw_service.hpp"
#include "horus/topic.hpp"
#include "horus/topic_registry.hpp"
#include "horus/view/codecs.hpp"
#include "protocol.hpp"
#include "service_test/compute.hpp"
#include "topic_test_support.hpp"

namespace {

using topic_test::PrivateNamespace;
using namespace std::chrono_literals;

/// WebSocket clients mask what they send with it; a test needs no real randomness.
class TestEntropy final : public kj::EntropySource {
 public:
  void generate(kj::ArrayPtr<kj::byte> buffer) override {
    for (kj::byte& b : buffer) b = static_cast<kj::byte>(random_());
  }

 private:
  std::minstd_rand random_{7};
};

struct ServiceResponse {
  std::uint32_t service = 0;
  std::uint32_t call = 0;
  std::string encoding;
  std::vector<std::byte> payload;
};

struct MessageData {
  std::uint32_t subscription = 0;
  std::uint64_t receive_time_ns = 0;
  std::vector<std::byte> payload;
};

/// One Foxglove WebSocket client on the test's event loop.
class ViewClient {
 public:
  ViewClient(kj::AsyncIoContext& io, std::uint16_t port, const std::string& subprotocols)
      : io_(io) {
    kj::HttpHeaderTable::Builder builder;
    protocol_ = builder.add("Sec-WebSocket-Protocol");
    table_ = builder.build();
    address_ = io_.provider->getNetwork().parseAddress("127.0.0.1", port).wait(io_.waitScope);
    kj::HttpClientSettings settings;
    settings.entropySource = entropy_;
    http_ = kj::newHttpClient(io_.provider->getTimer(), *table_, *address_, settings);
    kj::HttpHeaders headers(*table_);
    headers.set(kj::HttpHeaderId::HOST, "127.0.0.1");
    headers.set(protocol_, subprotocols);
    auto response = http_->openWebSocket("/", headers).wait(io_.waitScope);
    status_ = response.statusCode;
    KJ_IF_MAYBE (chosen, response.headers->get(protocol_)) {
      subprotocol_ = chosen->cStr();
    }
    KJ_SWITCH_ONEOF(response.webSocketOrBody) {
      KJ_CASE_ONEOF(body, kj::Own<kj::AsyncInputStream>) {
        body_ = body->readAllText().wait(io_.waitScope).cStr();
      }
      KJ_CASE_ONEOF(socket, kj::Own<kj::WebSocket>) { socket_ = kj::mv(socket); }
    }
  }

  unsigned status() const { return status_; }
  const std::string& subprotocol() const { return subprotocol_; }
  const std::string& body() const { return body_; }

  /// The next JSON message with op `op` (others are kept), or none within `timeout`.
  std::optional<std::string> next_text(const std::string& op,
                                       std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      for (auto it = texts_.begin(); it != texts_.end(); ++it) {
        const horus::view::ClientMessage message(*it);
        if (message.op() == op) {
          std::string text = std::move(*it);
          texts_.erase(it);
          return text;
        }
      }
      if (!receive_one(deadline)) return std::nullopt;
    }
  }

  /// The next Message Data, or none within `timeout`.
  std::optional<MessageData> next_data(std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (data_.empty()) {
      if (!receive_one(deadline)) return std::nullopt;
    }
    MessageData data = std::move(data_.front());
    data_.pop_front();
    return data;
  }

  /// The next Service Call Response, or none within `timeout`.
  std::optional<ServiceResponse> next_service_response(std::chrono::milliseconds timeout = 10s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (responses_.empty()) {
      if (!receive_one(deadline)) return std::nullopt;
    }
    ServiceResponse response = std::move(responses_.front());
    responses_.pop_front();
    return response;
  }

  void send_text(const std::string& text) {
    socket_->send(kj::arrayPtr(text.data(), text.size())).wait(io_.waitScope);
  }
  void send_binary(const std::vector<std::byte>& bytes) {
    socket_->send(kj::arrayPtr(reinterpret_cast<const kj::byte*>(bytes.data()), bytes.size()))
        .wait(io_.waitScope);
  }

 private:
  /// Receives one message into texts_ or data_ (Time messages are only checked); false when
  /// none came by `deadline`.
  bool receive_one(std::chrono::steady_clock::time_point deadline) {
    // The timer counts from the loop's last look at the clock, which a test that published for
    // a while without running the loop left behind: a look first.
    io_.waitScope.poll();
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    auto timed_out = io_.provider->getTimer()
                         .afterDelay(left.count() * kj::MILLISECONDS)
                         .then([]() -> kj::Maybe<kj::WebSocket::Message> { return nullptr; });
    auto message = socket_->receive(std::size_t{64} << 20)
                       .then([](kj::WebSocket::Message&& got) -> kj::Maybe<kj::WebSocket::Message> {
                         return kj::mv(got);
                       })
                       .exclusiveJoin(kj::mv(timed_out))
                       .wait(io_.waitScope);
    KJ_IF_MAYBE (got, message) {
      KJ_SWITCH_ONEOF(*got) {
        KJ_CASE_ONEOF(text, kj::String) { texts_.emplace_back(text.cStr()); }
        KJ_CASE_ONEOF(bytes, kj::Array<kj::byte>) {
          const std::span<const std::byte> raw(reinterpret_cast<const std::byte*>(bytes.begin()),
                                               bytes.size());
          EXPECT_FALSE(raw.empty());
          if (raw[0] == std::byte{2}) {
            EXPECT_EQ(raw.size(), 9u) << "a Time message is its opcode and a u64";
          } else if (raw[0] == std::byte{3}) {
            EXPECT_GE(raw.size(), 13u);
            ServiceResponse response;
            response.service = horus::view::read_u32(raw, 1);
            response.call = horus::view::read_u32(raw, 5);
            const std::uint32_t encoding_size = horus::view::read_u32(raw, 9);
            response.encoding.assign(reinterpret_cast<const char*>(raw.data()) + 13, encoding_size);
            response.payload.assign(raw.begin() + 13 + encoding_size, raw.end());
            responses_.push_back(std::move(response));
          } else {
            EXPECT_EQ(raw[0], std::byte{1}) << "a binary message that is not Message Data";
            EXPECT_GE(raw.size(), horus::view::kMessageDataHeader);
            MessageData data;
            data.subscription = horus::view::read_u32(raw, 1);
            std::memcpy(&data.receive_time_ns, raw.data() + 5, 8);
            data.payload.assign(raw.begin() + horus::view::kMessageDataHeader, raw.end());
            data_.push_back(std::move(data));
          }
        }
        KJ_CASE_ONEOF(close, kj::WebSocket::Close) {
          ADD_FAILURE() << "horus-view closed the connection: " << close.reason.cStr();
          return false;
        }
      }
      return true;
    }
    return false;
  }

  kj::AsyncIoContext& io_;
  TestEntropy entropy_;
  kj::HttpHeaderId protocol_ = kj::HttpHeaderId::HOST;
  kj::Own<kj::HttpHeaderTable> table_;
  kj::Own<kj::NetworkAddress> address_;
  kj::Own<kj::HttpClient> http_;
  unsigned status_ = 0;
  std::string subprotocol_;
  std::string body_;
  kj::Own<kj::WebSocket> socket_;
  std::deque<std::string> texts_;
  std::deque<MessageData> data_;
  std::deque<ServiceResponse> responses_;
};

/// The id of the channel of `topic` in an advertise, if it is there; its schemaName too.
std::optional<std::pair<std::uint32_t, std::string>> channel_in(const std::string& advertise,
                                                                const std::string& topic) {
  const horus::view::ClientMessage message(advertise);
  for (const auto channel : horus::view::array_member(message.root(), "channels", "test")) {
    if (horus::view::string_member(channel, "topic", "test") == topic) {
      return std::make_pair(horus::view::id_member(channel, "id", "test"),
                            horus::view::string_member(channel, "schemaName", "test"));
    }
  }
  return std::nullopt;
}

/// This process's resident memory, in KiB (/proc/self/status VmRSS).
std::size_t resident_kib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoul(line.substr(6));
  }
  return 0;
}

class ViewServerTest : public ::testing::Test {
 protected:
  ViewServerTest() {
    horus::LiveViewOptions options;
    options.namespace_name = ns_.name();
    options.port = 0;
    options.discovery_interval = 20ms;
    view_ = std::make_unique<horus::LiveView>(options);
    view_->start();
  }

  ViewClient connect(const std::string& subprotocols = "foxglove.websocket.v1") {
    return ViewClient(*io_, view_->port(), subprotocols);
  }

  /// Connects and returns the client with the channel of `topic` advertised to it.
  std::pair<std::uint32_t, std::string> channel_of(ViewClient& client, const std::string& topic) {
    for (;;) {
      const auto advertise = client.next_text("advertise");
      if (!advertise) {
        ADD_FAILURE() << "no advertise of '" << topic << "' came";
        return {};
      }
      if (auto channel = channel_in(*advertise, topic)) return *channel;
    }
  }

  PrivateNamespace ns_;
  // Held by pointer: its destructor may throw, which a test's may not.
  std::unique_ptr<kj::AsyncIoContext> io_ =
      std::make_unique<kj::AsyncIoContext>(kj::setupAsyncIo());
  std::unique_ptr<horus::LiveView> view_;
};

TEST_F(ViewServerTest, AnswersEachFoxgloveSubprotocolWithTheOneOffered) {
  for (const std::string offered : {"foxglove.websocket.v1", "foxglove.sdk.v1"}) {
    ViewClient client = connect(offered);
    ASSERT_EQ(client.status(), 101u) << client.body();
    EXPECT_EQ(client.subprotocol(), offered);
    const auto info = client.next_text("serverInfo");
    ASSERT_TRUE(info) << "no serverInfo after connecting with " << offered;
    const horus::view::ClientMessage message(*info);
    std::vector<std::string> capabilities;
    for (const auto capability :
         horus::view::array_member(message.root(), "capabilities", "serverInfo")) {
      capabilities.emplace_back(capability.getString().cStr());
    }
    EXPECT_NE(std::find(capabilities.begin(), capabilities.end(), "clientPublish"),
              capabilities.end());
    const auto encodings = horus::view::array_member(message.root(), "supportedEncodings", "");
    ASSERT_EQ(encodings.size(), 1u);
    EXPECT_EQ(std::string(encodings[0].getString().cStr()), "json");
    EXPECT_TRUE(client.next_text("advertise")) << "a new client is always sent an advertise";
  }
  // Of several offered, the first the server speaks.
  ViewClient client = connect("chat, foxglove.sdk.v1, foxglove.websocket.v1");
  EXPECT_EQ(client.status(), 101u);
  EXPECT_EQ(client.subprotocol(), "foxglove.sdk.v1");
}

TEST_F(ViewServerTest, RefusesAClientWithoutAFoxgloveSubprotocol) {
  ViewClient client = connect("chat.v2");
  EXPECT_EQ(client.status(), 400u);
  EXPECT_NE(client.body().find("foxglove.websocket.v1"), std::string::npos) << client.body();
  EXPECT_NE(client.body().find("chat.v2"), std::string::npos) << client.body();
}

TEST_F(ViewServerTest, AdvertisesATopicAndUnadvertisesItWhenItGoes) {
  auto topic = std::make_unique<horus::Topic<horus::msg::CmdVel>>("cmd_vel");
  ASSERT_TRUE(topic->send(horus::msg::CmdVel{1, 0.5f, 0.25f}));
  ViewClient client = connect();
  const auto [id, schema_name] = channel_of(client, "cmd_vel");
  const auto codec = horus::view::codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  EXPECT_EQ(schema_name, codec->schema().schema_name);

  topic.reset();
  horus::remove_created_topics_nobody_uses();
  const auto gone = client.next_text("unadvertise");
  ASSERT_TRUE(gone) << "the topic went, and no unadvertise came";
  const horus::view::ClientMessage message(*gone);
  const auto ids = horus::view::array_member(message.root(), "channelIds", "");
  ASSERT_EQ(ids.size(), 1u);
  EXPECT_EQ(horus::view::id_value(ids[0], ""), id);
}

TEST_F(ViewServerTest, ASubscriberIsSentMessageDataWithTheCodecsPayload) {
  horus::Topic<horus::msg::CmdVel> topic("cmd_vel");
  const horus::msg::CmdVel sent{42, 1.5f, -0.5f};
  ASSERT_TRUE(topic.send(sent));
  ViewClient client = connect();
  const auto [id, schema_name] = channel_of(client, "cmd_vel");
  client.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":7,\"channelId\":" +
                   std::to_string(id) + "}]}");
  // The newest message is sent at once on subscribing, and every one after.
  const auto before = std::chrono::system_clock::now();
  auto data = client.next_data();
  ASSERT_TRUE(data) << "no Message Data for the newest message on subscribing";
  ASSERT_TRUE(topic.send(sent));
  data = client.next_data();
  ASSERT_TRUE(data) << "no Message Data for a message sent after subscribing";
  EXPECT_EQ(data->subscription, 7u);
  const auto stamp = std::chrono::system_clock::time_point(
      std::chrono::duration_cast<std::chrono::system_clock::duration>(
          std::chrono::nanoseconds(data->receive_time_ns)));
  EXPECT_LT(std::chrono::abs(stamp - before), 10s) << "the receive time is CLOCK_REALTIME";

  const auto codec = horus::view::codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  std::vector<std::byte> expected;
  codec->encode(std::as_bytes(std::span(&sent, 1)), expected);
  EXPECT_EQ(data->payload, expected);

  // A channel that was never advertised is refused with a status, and the session goes on.
  client.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":8,\"channelId\":999}]}");
  const auto refused = client.next_text("status");
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("channel 999"), std::string::npos) << *refused;
}

// A message is framed once, for the first subscriber's id: a client subscribed under another id
// gets the same payload framed under its own.
TEST_F(ViewServerTest, ClientsSubscribedUnderOtherIdsGetTheSameMessageUnderTheirOwn) {
  horus::Topic<horus::msg::CmdVel> topic("cmd_vel");
  ViewClient first = connect();
  ViewClient second = connect("foxglove.sdk.v1");
  const auto [id, schema_name] = channel_of(first, "cmd_vel");
  EXPECT_EQ(channel_of(second, "cmd_vel").first, id);
  first.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":3,\"channelId\":" +
                  std::to_string(id) + "}]}");
  second.send_text(
      "{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":4000000001,"
      "\"channelId\":" +
      std::to_string(id) + "}]}");
  const auto codec = horus::view::codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  // Sent until both have subscribed and each has seen the newest message of the same stamp.
  for (std::uint64_t stamp = 1; stamp <= 200; ++stamp) {
    const horus::msg::CmdVel sent{stamp, 0.5f, static_cast<float>(stamp)};
    ASSERT_TRUE(topic.send(sent));
    auto a = first.next_data(200ms);
    auto b = second.next_data(200ms);
    if (!a || !b) continue;
    while (auto newer = first.next_data(20ms)) a = newer;
    while (auto newer = second.next_data(20ms)) b = newer;
    if (a->payload != b->payload) continue;  // one is a message behind: send another
    EXPECT_EQ(a->subscription, 3u);
    EXPECT_EQ(b->subscription, 4000000001u);
    std::vector<std::byte> expected;
    codec->encode(std::as_bytes(std::span(&sent, 1)), expected);
    EXPECT_EQ(a->payload, expected);
    EXPECT_EQ(b->payload, expected);
    return;
  }
  FAIL() << "the two clients were never sent the same newest message";
}

TEST_F(ViewServerTest, ASubscriptionWithMaxRateHzIsSentTheNewestAtThatRate) {
  horus::Topic<horus::msg::CmdVel> topic("cmd_vel");
  ViewClient client = connect();
  const auto [id, schema_name] = channel_of(client, "cmd_vel");
  client.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":1,\"channelId\":" +
                   std::to_string(id) + ",\"maxRateHz\":5}]}");
  std::this_thread::sleep_for(200ms);  // the feed starts
  horus::msg::CmdVel last{};
  const auto start = std::chrono::steady_clock::now();
  for (std::uint64_t i = 1; std::chrono::steady_clock::now() - start < 1s; ++i) {
    last = horus::msg::CmdVel{i, 1.0f, 0.0f};
    ASSERT_TRUE(topic.send(last));
    std::this_thread::sleep_for(2ms);
  }
  std::vector<MessageData> received;
  while (auto data = client.next_data(700ms)) received.push_back(std::move(*data));
  // About 5 in the second of publishing, and the newest after it.
  EXPECT_GE(received.size(), 3u);
  EXPECT_LE(received.size(), 9u);
  ASSERT_FALSE(received.empty());
  const auto codec = horus::view::codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  std::vector<std::byte> newest;
  codec->encode(std::as_bytes(std::span(&last, 1)), newest);
  EXPECT_EQ(received.back().payload, newest) << "the last message sent is the newest published";

  client.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":2,\"channelId\":" +
                   std::to_string(id) + ",\"maxRateHz\":0}]}");
  const auto refused = client.next_text("status");
  ASSERT_TRUE(refused);
  EXPECT_NE(refused->find("maxRateHz"), std::string::npos) << *refused;
}

TEST_F(ViewServerTest, AMessageAClientPublishesArrivesInTheTopic) {
  horus::Topic<horus::msg::CmdVel> topic("cmd_vel");
  ViewClient client = connect();
  const auto [id, schema_name] = channel_of(client, "cmd_vel");
  client.send_text(
      "{\"op\":\"advertise\",\"channels\":[{\"id\":3,\"topic\":\"cmd_vel\",\"encoding\":\"json\","
      "\"schemaName\":\"" +
      schema_name + "\"}]}");
  const horus::msg::CmdVel published{7, 0.75f, 0.125f};
  const auto codec = horus::view::codec_for(horus::type_identity<horus::msg::CmdVel>(), "cmd_vel");
  std::vector<std::byte> payload;
  codec->encode(std::as_bytes(std::span(&published, 1)), payload);
  std::vector<std::byte> message{std::byte{1}, std::byte{3}, std::byte{0}, std::byte{0},
                                 std::byte{0}};
  message.insert(message.end(), payload.begin(), payload.end());
  client.send_binary(message);

  std::optional<horus::msg::CmdVel> received;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!received && std::chrono::steady_clock::now() < deadline) {
    received = topic.recv(100ms);
  }
  ASSERT_TRUE(received) << "the published message never reached the topic";
  EXPECT_EQ(*received, published);
  // Counted on the server's thread just after the message went.
  for (int i = 0; i < 100 && view_->counters().messages_published == 0; ++i) {
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_EQ(view_->counters().messages_published, 1u);

  // Into a topic that does not exist: refused, with the reason.
  client.send_text(
      "{\"op\":\"advertise\",\"channels\":[{\"id\":4,\"topic\":\"no_such\",\"encoding\":\"json\","
      "\"schemaName\":\"" +
      schema_name + "\"}]}");
  auto status = client.next_text("status");
  ASSERT_TRUE(status);
  EXPECT_NE(status->find("no such topic"), std::string::npos) << *status;
  // Under another type's name: refused.
  client.send_text(
      "{\"op\":\"advertise\",\"channels\":[{\"id\":5,\"topic\":\"cmd_vel\",\"encoding\":\"json\","
      "\"schemaName\":\"horus.msg.Twist\"}]}");
  status = client.next_text("status");
  ASSERT_TRUE(status);
  EXPECT_NE(status->find("horus.msg.Twist"), std::string::npos) << *status;
  // On a channel that was refused: not published.
  message[1] = std::byte{4};
  client.send_binary(message);
  status = client.next_text("status");
  ASSERT_TRUE(status);
  EXPECT_NE(status->find("not published"), std::string::npos) << *status;
  EXPECT_FALSE(topic.recv(200ms)) << "a refused message reached the topic";
}

TEST_F(ViewServerTest, AGraphWatcherIsSentTheWholeGraphThenWhatChanges) {
  ViewClient client = connect();
  client.send_text("{\"op\":\"subscribeConnectionGraph\"}");
  ASSERT_TRUE(client.next_text("connectionGraphUpdate")) << "no graph on subscribing to it";

  const horus::RawServiceType type = horus::raw_service_type<service_test::Compute>();
  horus::RawServiceServer server(type);
  const auto update = client.next_text("connectionGraphUpdate");
  ASSERT_TRUE(update) << "a service server came and the graph did not change";
  const horus::view::ClientMessage message(*update);
  const auto services = horus::view::array_member(message.root(), "advertisedServices", "");
  ASSERT_EQ(services.size(), 1u) << *update;
  EXPECT_EQ(horus::view::string_member(services[0], "name", ""), type.name);
  const auto providers = horus::view::array_member(services[0], "providerIds", "");
  ASSERT_EQ(providers.size(), 1u) << *update;
  EXPECT_NE(
      std::string(providers[0].getString().cStr()).find("(pid " + std::to_string(::getpid()) + ")"),
      std::string::npos)
      << *update;
}

TEST_F(ViewServerTest, AServiceCallIsAnsweredByTheServiceServer) {
  using service_test::Compute;
  const horus::RawServiceType type = horus::raw_service_type<Compute>();
  horus::RawServiceServer server(type);
  std::thread serving([&] {
    while (!server.stopped()) {
      const auto request = server.next(50ms);
      if (!request) continue;
      Compute::Request asked{};
      std::memcpy(&asked, request->payload.data(), sizeof(asked));
      const Compute::Response answer{asked.a + asked.b, static_cast<std::uint32_t>(::getpid())};
      server.answer(request->caller, std::as_bytes(std::span(&answer, 1)));
    }
  });
  ViewClient client = connect();
  std::optional<std::uint32_t> service_id;
  while (!service_id) {
    const auto advertised = client.next_text("advertiseServices");
    ASSERT_TRUE(advertised) << "the service was never advertised";
    const horus::view::ClientMessage message(*advertised);
    for (const auto service : horus::view::array_member(message.root(), "services", "")) {
      if (horus::view::string_member(service, "name", "") == type.name) {
        service_id = horus::view::id_member(service, "id", "");
      }
    }
  }
  // The request as the codec of its type writes it; the answer as the response's codec does.
  const Compute::Request asked{2, 40, 0, 0};
  std::vector<std::byte> json;
  horus::view::codec_for(type.request, type.name)
      ->encode(std::as_bytes(std::span(&asked, 1)), json);
  std::vector<std::byte> call{std::byte{2}};
  const auto put_u32 = [&](std::uint32_t value) {
    for (int i = 0; i < 4; ++i) call.push_back(static_cast<std::byte>(value >> (8 * i)));
  };
  put_u32(*service_id);
  put_u32(77);
  put_u32(4);
  for (const char c : std::string("json")) call.push_back(static_cast<std::byte>(c));
  call.insert(call.end(), json.begin(), json.end());
  client.send_binary(call);

  const auto response = client.next_service_response();
  ASSERT_TRUE(response) << "no Service Call Response";
  EXPECT_EQ(response->service, *service_id);
  EXPECT_EQ(response->call, 77u);
  EXPECT_EQ(response->encoding, "json");
  const Compute::Response expected{42, static_cast<std::uint32_t>(::getpid())};
  std::vector<std::byte> expected_json;
  horus::view::codec_for(type.response, type.name)
      ->encode(std::as_bytes(std::span(&expected, 1)), expected_json);
  EXPECT_EQ(response->payload, expected_json);

  // A service never advertised: a serviceCallFailure naming the call.
  call[1] = std::byte{99};
  client.send_binary(call);
  const auto failure = client.next_text("serviceCallFailure");
  ASSERT_TRUE(failure);
  EXPECT_NE(failure->find("\"callId\":77"), std::string::npos) << *failure;
  server.stop();
  serving.join();
}

TEST_F(ViewServerTest, AClientThatStopsReadingHasDropsCountedAndHoldsOneMessage) {
  constexpr std::size_t kImageBytes = std::size_t{1} << 20;
  horus::TopicOptions options;
  options.capacity = 8;
  options.max_message_size = kImageBytes + 4096;
  horus::Topic<horus::msg::CompressedImage> topic("camera", options);
  horus::msg::CompressedImage image;
  image.format = "jpeg";
  image.data.assign(kImageBytes, 0x5a);
  image.width = 1024;
  image.height = 1024;
  {
    // The codec shows this type: drops below are the client's, not refused frames.
    const auto codec =
        horus::view::codec_for(horus::type_identity<horus::msg::CompressedImage>(), "camera");
    const std::vector<std::uint8_t> encoded = horus::encode(image);
    std::vector<std::byte> payload;
    ASSERT_NO_THROW(codec->encode(std::as_bytes(std::span(encoded)), payload));
  }
  ASSERT_TRUE(topic.send(image));
  ViewClient client = connect();
  const auto [id, schema_name] = channel_of(client, "camera");
  client.send_text("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":1,\"channelId\":" +
                   std::to_string(id) + "}]}");
  ASSERT_TRUE(client.next_data()) << "no first image";

  // The client reads nothing more: its socket fills, then each image replaces the unsent one.
  const auto publish = [&](int count) {
    for (int i = 0; i < count; ++i) {
      ASSERT_TRUE(topic.send(image));
      std::this_thread::sleep_for(2ms);
    }
  };
  publish(40);
  const std::size_t warmed_up = resident_kib();
  const std::uint64_t dropped_before = view_->counters().messages_dropped;
  publish(300);
  std::this_thread::sleep_for(200ms);
  const std::size_t now_kib = resident_kib();
  const std::size_t grown_kib = now_kib > warmed_up ? now_kib - warmed_up : 0;
  const horus::LiveViewCounters counted = view_->counters();
  EXPECT_GT(counted.messages_dropped - dropped_before, 200u)
      << "300 images of 1 MiB to a client that reads nothing";
  EXPECT_LT(counted.messages_sent, 60u) << "more images were sent than sockets can hold";
  // 300 MiB went by; the server holds one pending image per channel and the one in flight.
  EXPECT_LT(grown_kib, 64u * 1024) << "the server's memory grew by " << grown_kib << " KiB";
  const std::string status = view_->status_json();
  EXPECT_NE(status.find("\"topic\": \"camera\""), std::string::npos) << status;
}

// Who a client is: the tokens file (access.hpp) and the start-up rules of the options.

/// The message of the horus::Error `parse` throws for `text`, or "" when it throws none.
std::string token_file_error(const std::string& text) {
  try {
    horus::view::PeerTokens::parse(text, "tokens");
  } catch (const horus::Error& error) {
    return error.what();
  }
  return "";
}

TEST(ViewTokensTest, NamesThePeerOfEachTokenAndNoneForAnUnknownOne) {
  const auto tokens = horus::view::PeerTokens::parse(
      "# who may look\n\nalice 0123456789abcdef-alice\n  bob\t0123456789abcdef-bob  \n", "tokens");
  EXPECT_EQ(tokens.size(), 2u);
  EXPECT_EQ(tokens.peer_of("0123456789abcdef-alice"), "alice");
  EXPECT_EQ(tokens.peer_of("0123456789abcdef-bob"), "bob");
  EXPECT_EQ(tokens.peer_of("0123456789abcdef-carol"), std::nullopt);
  EXPECT_EQ(tokens.peer_of(""), std::nullopt);
}

TEST(ViewTokensTest, AMalformedLineIsRefusedNamingTheFileLineAndWhy) {
  EXPECT_EQ(token_file_error("alice 0123456789abcdef-alice\nbob\n"),
            "tokens:2: 'bob' is not 'PEER TOKEN'");
  EXPECT_EQ(token_file_error("alice 0123456789abcdef-alice extra\n"),
            "tokens:1: 'alice 0123456789abcdef-alice extra' is not 'PEER TOKEN'");
  const std::string short_token = token_file_error("\n# fine\nalice secret\n");
  EXPECT_NE(short_token.find("tokens:3: the token of 'alice' is 6 characters, fewer than 16"),
            std::string::npos)
      << short_token;
  const std::string shared =
      token_file_error("alice 0123456789abcdef-same\nbob 0123456789abcdef-same\n");
  EXPECT_NE(shared.find("tokens:2: the token of 'bob' is also the token of 'alice'"),
            std::string::npos)
      << shared;
}

TEST(ViewTokensTest, ATokensFileOthersMayReadIsRefusedOnTheOpenedFile) {
  char folder_template[] = "/tmp/horus-view-tokens-XXXXXX";
  ASSERT_NE(::mkdtemp(folder_template), nullptr);
  const std::string path = std::string(folder_template) + "/tokens";
  std::ofstream(path) << "alice 0123456789abcdef-alice\n";
  ASSERT_EQ(::chmod(path.c_str(), 0600), 0);
  EXPECT_EQ(horus::view::PeerTokens::load(path).peer_of("0123456789abcdef-alice"), "alice");
  ASSERT_EQ(::chmod(path.c_str(), 0640), 0);
  try {
    horus::view::PeerTokens::load(path);
    ADD_FAILURE() << "a tokens file of mode 0640 was read";
  } catch (const horus::Error& error) {
    EXPECT_EQ(std::string(error.what()), "the tokens file " + path +
                                             " has mode 0640: group or others may read or "
                                             "change its tokens; chmod 600 " +
                                             path);
  }
  ::unlink(path.c_str());
  try {
    horus::view::PeerTokens::load(path);
    ADD_FAILURE() << "a missing tokens file was read";
  } catch (const horus::Error& error) {
    EXPECT_NE(std::string(error.what()).find("cannot read the tokens file " + path),
              std::string::npos)
        << error.what();
  }
  ::rmdir(folder_template);
}

TEST(ViewTokensTest, TheTokenIsTakenFromTheUrlsQueryDecoded) {
  using horus::view::token_of_target;
  EXPECT_EQ(token_of_target("/?token=abc%21def"), "abc!def");
  EXPECT_EQ(token_of_target("/index.html?view=1&token=t0k3n#top"), "t0k3n");
  EXPECT_EQ(token_of_target("/?token="), "");
  EXPECT_EQ(token_of_target("/"), std::nullopt);
  EXPECT_EQ(token_of_target("/?tokens=abc&xtoken=abc"), std::nullopt);
}

TEST(ViewAccessOptionsTest, AnAddressBeyondThisMachineNeedsTlsAndAPolicy) {
  EXPECT_TRUE(horus::detail::is_loopback_address("127.0.0.1"));
  EXPECT_TRUE(horus::detail::is_loopback_address("127.8.0.2"));
  EXPECT_TRUE(horus::detail::is_loopback_address("::1"));
  EXPECT_TRUE(horus::detail::is_loopback_address("localhost"));
  EXPECT_FALSE(horus::detail::is_loopback_address("0.0.0.0"));
  EXPECT_FALSE(horus::detail::is_loopback_address("::"));
  EXPECT_FALSE(horus::detail::is_loopback_address("192.168.1.20"));
  EXPECT_FALSE(horus::detail::is_loopback_address("robot.local"));

  horus::LiveViewOptions wide;
  wide.listen_address = "0.0.0.0";
  wide.policy_lines = {"alice read *"};
  wide.tokens_file = "/nonexistent/tokens";
  horus::LiveView view(wide);
  try {
    view.start();
    ADD_FAILURE() << "a view on 0.0.0.0 without TLS started";
  } catch (const horus::Error& error) {
    const std::string said = error.what();
    EXPECT_NE(said.find("listening on 0.0.0.0"), std::string::npos) << said;
    EXPECT_NE(said.find("add --tls DIR --name NAME"), std::string::npos) << said;
    EXPECT_EQ(said.find("--allow"), std::string::npos) << "the policy was given: " << said;
  }

  horus::LiveViewOptions no_one;  // a policy, and no way to authenticate for it
  no_one.port = 0;
  no_one.policy_lines = {"alice read *"};
  EXPECT_THROW(horus::detail::check_live_view(no_one), horus::Error);
}

}  // namespace
