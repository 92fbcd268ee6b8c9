// The complete example of seed 004 (services), end to end: KeyValueStore (tests/support/
// key_value_store.hsrv) served and called as the seed does in one process, then with the store
// in another process that two clients share.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <kv_example/key_value_store.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using kv_example::KeyValueStore;
using kv_example::KeyValueStoreRequest;
using kv_example::KeyValueStoreResponse;
using topic_test::Child;
using topic_test::PrivateNamespace;

constexpr auto kLong = 20s;
constexpr const char* kStopTopic = "kv_test.stop";

/// The seed's server: a map behind a mutex; a request with a value sets it, one without gets it.
horus::ServiceServer<KeyValueStore> serve_store(std::map<std::string, std::string>& store,
                                                std::mutex& lock) {
  return horus::ServiceServerBuilder<KeyValueStore>()
      .on_request([&store, &lock](KeyValueStoreRequest req) {
        const std::lock_guard<std::mutex> held(lock);
        if (req.value) {
          store[req.key] = *req.value;
          return KeyValueStoreResponse{req.value, true};
        }
        const auto found = store.find(req.key);
        if (found == store.end()) {
          return KeyValueStoreResponse{std::nullopt, false};
        }
        return KeyValueStoreResponse{found->second, true};
      })
      .build();
}

/// kv_serve: serves the store until a message arrives on kStopTopic (or 60 s).
int role_kv_serve(const std::vector<std::string>&) {
  horus::Topic<bool> stop(kStopTopic);
  std::map<std::string, std::string> store;
  std::mutex lock;
  const horus::ServiceServer<KeyValueStore> server = serve_store(store, lock);
  return stop.recv(60s) ? 0 : 30;
}

/// kv_set <key> <value>: one set call from a client of its own; 0 when the store echoed it.
int role_kv_set(const std::vector<std::string>& args) {
  horus::ServiceClient<KeyValueStore> client;
  if (!client.wait_for_server(kLong)) {
    return 40;
  }
  const horus::ServiceResult<KeyValueStoreResponse> set =
      client.call(KeyValueStoreRequest{args.at(0), args.at(1)}, kLong);
  return set && set->found && set->value == args.at(1) ? 0 : 41;
}

const bool kRolesRegistered = [] {
  topic_test::roles()["kv_serve"] = role_kv_serve;
  topic_test::roles()["kv_set"] = role_kv_set;
  topic_test::dispatch_role();
  return true;
}();

TEST(KeyValueStore, TheSeedsExampleInOneProcess) {
  PrivateNamespace ns;
  std::map<std::string, std::string> store;
  std::mutex lock;
  const horus::ServiceServer<KeyValueStore> server = serve_store(store, lock);

  horus::ServiceClient<KeyValueStore> client;
  const horus::ServiceResult<KeyValueStoreResponse> set =
      client.call(KeyValueStoreRequest{"robot_id", "arm_01"}, 1s);
  ASSERT_TRUE(set) << set.error().to_string();
  const horus::ServiceResult<KeyValueStoreResponse> res =
      client.call(KeyValueStoreRequest{"robot_id", std::nullopt}, 1s);
  ASSERT_TRUE(res) << res.error().to_string();
  EXPECT_EQ(res->value, std::optional<std::string>("arm_01"));
  EXPECT_TRUE(res->found);

  const horus::ServiceResult<KeyValueStoreResponse> missing =
      client.call(KeyValueStoreRequest{"serial", std::nullopt}, 1s);
  ASSERT_TRUE(missing) << missing.error().to_string();
  EXPECT_FALSE(missing->found);
  EXPECT_FALSE(missing->value.has_value());
  // The handler's thread owns the map under `lock`; the test reads it the same way.
  const std::lock_guard<std::mutex> held(lock);
  EXPECT_EQ(store.at("robot_id"), "arm_01");
}

TEST(KeyValueStore, AStoreInAnotherProcessIsSharedByItsClients) {
  PrivateNamespace ns;
  Child server("kv_serve", {});
  horus::ServiceClient<KeyValueStore> client;
  ASSERT_TRUE(client.wait_for_server(kLong)) << "the store never registered";

  Child writer("kv_set", {"robot_id", "arm_01"});
  ASSERT_EQ(writer.wait(kLong), 0);
  const horus::ServiceResult<KeyValueStoreResponse> res =
      client.call(KeyValueStoreRequest{"robot_id", std::nullopt}, kLong);
  ASSERT_TRUE(res) << res.error().to_string();
  EXPECT_EQ(res->value, std::optional<std::string>("arm_01"))
      << "the value another client set did not reach this one";
  EXPECT_TRUE(res->found);

  horus::Topic<bool> stop(kStopTopic);
  ASSERT_TRUE(stop.send(true));
  EXPECT_EQ(server.wait(kLong), 0);
  const horus::ServiceResult<KeyValueStoreResponse> after =
      client.call(KeyValueStoreRequest{"robot_id", std::nullopt}, 1s);
  ASSERT_FALSE(after);
  EXPECT_EQ(after.error().kind(), horus::ServiceErrorKind::NoServer);
}

}  // namespace
