// A namespace's log ring and presence folder (no /dev/shm growth; `horus
// shm clean`): kept while a live process writes the ring or runs a Scheduler there, removed by
// clean_namespace() / clean_presence() once the last one is gone, by the last Scheduler's
// destructor (the folder), and by remove_namespace() regardless.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <horus/log.hpp>
#include <horus/presence.hpp>
#include <horus/scheduler.hpp>
#include <horus/topic_registry.hpp>

#include "topic_test_support.hpp"

namespace {

using topic_test::Child;
using topic_test::PrivateNamespace;

class Idle : public horus::Node {
 public:
  std::string_view name() const override { return "idle"; }
  void tick() override {}
};

/// Logs a line (opening the namespace's ring) and runs a Scheduler (announcing in the presence
/// folder) until killed.
int role_log_and_run(const std::vector<std::string>&) {
  HORUS_LOG_INFO("a line for the namespace's ring");
  horus::Scheduler scheduler;
  scheduler.add(std::make_unique<Idle>()).build();
  scheduler.run();
  return 0;
}

const bool kRolesRegistered = [] {
  topic_test::roles()["log_and_run"] = role_log_and_run;
  return true;
}();
// Runs before main: a re-executed child plays its role and exits here.
const int kRoleStatus = topic_test::dispatch_role();

/// The kinds of the namespace's objects ("@logs", "@presence") and whether each is in use.
std::vector<std::pair<std::string, bool>> objects(const std::string& ns) {
  std::vector<std::pair<std::string, bool>> out;
  for (const horus::NamespaceObjectInfo& object : horus::list_namespace_objects(ns)) {
    out.emplace_back(object.kind, object.in_use);
  }
  return out;
}

/// Polls until `done` (the child needs time to start); false after a minute.
template <class Predicate>
bool eventually(Predicate done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(1);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

bool exists(const std::string& path) {
  std::error_code ignored;
  return std::filesystem::exists(path, ignored);
}

}  // namespace

TEST(NamespaceCleanup, KeptWhileALiveProcessUsesThemRemovedOnceItDies) {
  PrivateNamespace ns;
  Child child("log_and_run", {});
  ASSERT_TRUE(eventually([&] {
    const auto presence = horus::list_presence(ns.name());
    return objects(ns.name()).size() == 2 && presence.size() == 1 && presence[0].alive;
  })) << "the child never logged and announced";
  const std::vector<horus::NamespaceObjectInfo> listed = horus::list_namespace_objects(ns.name());
  const std::string ring = listed[0].path;
  const std::string folder = listed[1].path;
  EXPECT_GT(listed[0].size, 0U);
  EXPECT_GT(listed[1].size, 0U) << "the announcement's bytes";

  EXPECT_EQ(horus::clean_namespace(ns.name()), 0U);
  EXPECT_EQ(horus::clean_presence(ns.name()), 0U);
  const std::vector<std::pair<std::string, bool>> live = {{"@logs", true}, {"@presence", true}};
  EXPECT_EQ(objects(ns.name()), live) << "a live process's ring and folder were touched";
  EXPECT_TRUE(exists(ring));
  EXPECT_TRUE(exists(folder));
  EXPECT_FALSE(horus::read_log(ns.name()).records.empty());

  child.kill();  // no destructor runs: the announcement stays behind, the locks go
  const std::vector<std::pair<std::string, bool>> dead = {{"@logs", false}, {"@presence", false}};
  EXPECT_EQ(objects(ns.name()), dead);
  EXPECT_EQ(horus::clean_namespace(ns.name()), 0U) << "no topic segment to count";
  EXPECT_FALSE(exists(ring));
  EXPECT_TRUE(exists(folder)) << "the dead announcement is clean_presence()'s to remove";
  EXPECT_EQ(horus::clean_presence(ns.name()), 1U);
  EXPECT_FALSE(exists(folder));
  EXPECT_TRUE(objects(ns.name()).empty());
}

TEST(NamespaceCleanup, AnAnnouncementHalfWrittenByAKilledProcessIsCleaned) {
  PrivateNamespace ns;
  Child child("log_and_run", {});
  ASSERT_TRUE(eventually([&] {
    const auto presence = horus::list_presence(ns.name());
    return presence.size() == 1 && presence[0].alive;
  })) << "the child never announced";
  const std::string folder = horus::list_namespace_objects(ns.name()).at(1).path;
  const std::uint32_t dead_pid = static_cast<std::uint32_t>(child.pid());
  child.kill();
  // An announcement is written aside and renamed: a kill mid-write leaves the aside file.
  const std::string dead_writer = folder + "/" + std::to_string(dead_pid) + ".7.tmp";
  const std::string live_writer = folder + "/" + std::to_string(::getpid()) + ".7.tmp";
  std::ofstream(dead_writer) << "horus-presence 1 ";
  std::ofstream(live_writer) << "horus-presence 1 ";

  EXPECT_EQ(horus::clean_presence(ns.name()), 2U) << "the dead announcement and its aside file";
  EXPECT_FALSE(exists(dead_writer));
  EXPECT_TRUE(exists(live_writer)) << "a live process may be writing its announcement";
  EXPECT_TRUE(exists(folder));
  std::filesystem::remove(live_writer);
  EXPECT_EQ(horus::clean_presence(ns.name()), 0U);
  EXPECT_FALSE(exists(folder));
}

TEST(NamespaceCleanup, TheLastSchedulerRemovesThePresenceFolder) {
  PrivateNamespace ns;
  // The namespace's presence folder as objects() lists it (a Scheduler may log, making a ring).
  const auto presence = [&] {
    std::vector<std::pair<std::string, bool>> found;
    for (const auto& object : objects(ns.name())) {
      if (object.first == "@presence") found.push_back(object);
    }
    return found;
  };
  auto first = std::make_unique<horus::Scheduler>();
  auto second = std::make_unique<horus::Scheduler>();
  const std::vector<std::pair<std::string, bool>> in_use = {{"@presence", true}};
  ASSERT_EQ(presence(), in_use) << "announcers lock the folder before announcing";
  EXPECT_EQ(horus::clean_presence(ns.name()), 0U);
  horus::clean_namespace(ns.name());
  EXPECT_EQ(presence(), in_use) << "removed under a live Scheduler";

  first.reset();
  EXPECT_EQ(presence(), in_use) << "the second Scheduler still announces there";
  second.reset();
  EXPECT_TRUE(presence().empty());
}

TEST(NamespaceCleanup, AWriterWhoseRingWasRemovedMakesANewOne) {
  PrivateNamespace ns;
  Child first("log_and_run", {});
  // The folder appears before the Scheduler's announcement is in it: killed in between, it would
  // leave an empty folder that cleaning rightly removes (seen on a loaded machine).
  ASSERT_TRUE(eventually(
      [&] { return objects(ns.name()).size() == 2 && !horus::list_presence(ns.name()).empty(); }));
  first.kill();
  horus::clean_namespace(ns.name());
  ASSERT_TRUE(horus::list_namespace_objects(ns.name()).size() == 1) << "the dead announcement";

  Child second("log_and_run", {});
  ASSERT_TRUE(eventually([&] { return !horus::read_log(ns.name()).records.empty(); }))
      << "the second writer never made a new ring";
  EXPECT_EQ(objects(ns.name()).front(), (std::pair<std::string, bool>{"@logs", true}));
}

TEST(NamespaceCleanup, LiveWritersShareTheRingWhileCleaningKeepsIt) {
  PrivateNamespace ns;
  Child first("log_and_run", {});
  Child second("log_and_run", {});
  // Each writer holds its lock for life: a second opener must neither wait for the first nor
  // make a ring of its own.
  const auto both_logged = [&] {
    horus::clean_namespace(ns.name());
    bool from_first = false;
    bool from_second = false;
    for (const horus::LogRecord& record : horus::read_log(ns.name()).records) {
      from_first = from_first || record.pid == static_cast<std::uint32_t>(first.pid());
      from_second = from_second || record.pid == static_cast<std::uint32_t>(second.pid());
    }
    return from_first && from_second;
  };
  EXPECT_TRUE(eventually(both_logged)) << "both writers' lines in one ring";
  first.kill();
  horus::clean_namespace(ns.name());
  EXPECT_EQ(objects(ns.name()).front(), (std::pair<std::string, bool>{"@logs", true}))
      << "the second writer still uses the ring";
  second.kill();
  horus::clean_namespace(ns.name());
  horus::clean_presence(ns.name());
  const auto left = objects(ns.name());
  EXPECT_TRUE(left.empty()) << left.front().first << (left.front().second ? " in use" : "");
}

TEST(NamespaceCleanup, RemoveNamespaceRemovesEvenWhatALiveProcessUses) {
  PrivateNamespace ns;
  HORUS_LOG_INFO("this process's first line opens this namespace's ring");
  horus::Scheduler scheduler;
  ASSERT_EQ(objects(ns.name()).size(), 2U);
  horus::remove_namespace(ns.name());
  EXPECT_TRUE(objects(ns.name()).empty());
}
