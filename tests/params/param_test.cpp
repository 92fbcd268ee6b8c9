// Parameters across real processes: declared by a node, read by another process, written
// through the owner (never during a tick, never beside another callback), refused with reasons,
// persisted for the next start, one owner at a time, a SIGKILLed owner's store taken over, YAML
// files, and the store as `horus shm list/clean` see it.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/file.h>

#include <cstdio>
#include <fstream>
#include <random>
#include <set>
#include <thread>

#include "horus/literals.hpp"
#include "horus/scheduler.hpp"
#include "horus/topic_registry.hpp"
#include "param_test_support.hpp"
#include "topic_test_support.hpp"

using namespace horus::literals;
using horus_test::eventually;
using horus_test::Motor;
using horus_test::packed;
using horus_test::packed_list;
using horus_test::store_owned;
using topic_test::Child;

namespace {

const std::string shm_root = horus_test::shared_root("params");

horus::SchedulerConfig real_time() {
  return horus::SchedulerConfig{}.tick_rate(200_hz).handle_signals(false);
}

/// Runs a scheduler with `node` on a thread of its own until stop().
class Running {
 public:
  explicit Running(std::shared_ptr<horus::Node> node, horus::SchedulerConfig config = real_time())
      : scheduler_(std::move(config)) {
    scheduler_.add(std::move(node)).rate(200_hz).build();
    thread_ = std::thread([this] { scheduler_.run(); });
  }
  ~Running() { stop(); }
  void stop() {
    scheduler_.stop();
    if (thread_.joinable()) thread_.join();
  }

 private:
  horus::Scheduler scheduler_;
  std::thread thread_;
};

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = shm_root + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// ---- Child roles --------------------------------------------------------------------------------

/// Reads the motor's parameters from another process: 0 when they are as the parent set them.
int read_role(const std::vector<std::string>& args) {
  const horus::ParamStoreReader reader("motor");
  if (!reader.owner_alive()) return 2;
  if (horus_test::number_of(reader.get("max_speed").value) != std::stod(args.at(0))) return 3;
  if (horus_test::text_of(reader.get("profile").value) != "eco") return 4;
  if (reader.get("max_speed").declaration.unit != "m/s") return 5;
  if (reader.get("max_speed").declaration.doc != "Top speed.") return 6;
  if (reader.list().size() != 7) return 7;
  return 0;
}

/// Writes through the owner from another process; 0 when accepted.
int set_role(const std::vector<std::string>& args) {
  horus::ParamSetOptions options;
  options.source = "horus param";
  const horus::ParamSetResult result =
      horus::set_param("motor", args.at(0), packed(std::stod(args.at(1))), options);
  return result.accepted ? 0 : 1;
}

/// Owns the motor for a while (a scheduler running it).
int own_role(const std::vector<std::string>&) {
  auto motor = std::make_shared<Motor>();
  horus::Scheduler scheduler(real_time());
  scheduler.add(motor).rate(100_hz).build();
  scheduler.run_for(std::chrono::seconds(20));
  return 0;
}

/// Owns the motor and writes its string and array without pause (through its own service), so
/// a SIGKILL lands mid-write.
int frantic_owner_role(const std::vector<std::string>& args) {
  auto motor = std::make_shared<Motor>();
  horus::Scheduler scheduler(real_time());
  scheduler.add(motor).rate(1000_hz).build();
  std::thread writer([&] {
    // From the start of the run: before it, there is no store to write to.
    if (!eventually([] { return store_owned("motor"); })) std::_Exit(3);
    std::uint64_t n = std::stoull(args.at(0)) * 1'000'000;
    for (;; ++n) {
      const std::string text = "v" + std::to_string(n) + std::string(40 + n % 100, 'a' + n % 26);
      const double d = static_cast<double>(n % 1000) / 1000.0;
      try {
        horus::set_param("motor", "label", packed(text));
        horus::set_param("motor", "gains", packed_list({d, d, d}));
      } catch (const horus::Error& e) {
        // Only a write that cannot be made ends the writer; the test's reader sees it stop.
        std::fprintf(stderr, "frantic_owner: %s\n", e.what());
        std::_Exit(4);
      }
    }
  });
  writer.detach();
  scheduler.run_for(std::chrono::seconds(30));
  return 0;
}

[[maybe_unused]] const bool roles_registered = [] {
  topic_test::roles()["read"] = read_role;
  topic_test::roles()["set"] = set_role;
  topic_test::roles()["own"] = own_role;
  topic_test::roles()["frantic_owner"] = frantic_owner_role;
  topic_test::dispatch_role();
  return true;
}();

// ---- Declarations
// ---------------------------------------------------------------------------------

class Bad : public horus::Node {
 public:
  void tick() override {}
  template <class T>
  void declare(std::string name, T value, horus::ParamOptions<T> options = {}) {
    declare_param<T>(std::move(name), std::move(value), std::move(options));
  }
};

}  // namespace

TEST(ParamDeclaration, RefusesBadNamesDuplicatesAndDefaultsOutsideTheirDeclaration) {
  Bad node;
  node.declare<double>("speed", 1.0);
  EXPECT_THROW(node.declare<double>("speed", 1.0), horus::ParamError);
  EXPECT_THROW(node.declare<double>("Speed", 1.0), horus::ParamError);
  EXPECT_THROW(node.declare<double>("9lives", 1.0), horus::ParamError);
  EXPECT_THROW(node.declare<double>("fast", 3.0, {.max = 2.0}), horus::ParamError);
  const horus::ParamOptions<std::string> choices{.choices = {"a", "b"}};
  EXPECT_THROW(node.declare<std::string>("mode", "x", choices), horus::ParamError);
  EXPECT_THROW(node.declare<std::string>("long", std::string(300, 'x')), horus::ParamError);
  using Big = std::array<double, 40>;
  EXPECT_THROW(node.declare<Big>("big", Big{}), horus::ParamError);
  EXPECT_EQ(node.param_declarations().size(), 1U);
  EXPECT_EQ(node.param_declarations()[0].spelling, "f64");
}

TEST(ParamDeclaration, HandlesReadDefaultsBeforeAStoreExists) {
  Motor motor;
  EXPECT_EQ(motor.max_speed.get(), 1.0);
  EXPECT_EQ(motor.profile.get(), "eco");
  EXPECT_EQ(motor.gains.get(), (std::array<double, 3>{1.0, 0.5, 0.0}));
  EXPECT_EQ(motor.max_speed.version(), 1U);
  EXPECT_EQ(motor.param_declarations()[3].spelling, "[f64; 3]");
}

TEST(ParamDeclaration, TypeDescriptionCarriesTheDeclarationKeys) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  const horus::ParamStoreReader reader("motor");
  const horus::TypeDescription& description = reader.description();
  const horus::MessageField* speed = description.root_message().find_field("max_speed");
  ASSERT_NE(speed, nullptr);
  EXPECT_EQ(speed->doc.value_or(""), "Top speed.");
  ASSERT_TRUE(speed->range.has_value());
  EXPECT_EQ(speed->range->min, 0.0);
  EXPECT_EQ(speed->range->max, 2.0);
  EXPECT_FALSE(speed->read_only.has_value());
  const horus::MessageField* wheels = description.root_message().find_field("wheel_count");
  EXPECT_TRUE(wheels->read_only.value_or(false));
  const horus::MessageField* profile = description.root_message().find_field("profile");
  ASSERT_TRUE(profile->choices.has_value());
  EXPECT_EQ(profile->choices->size(), 2U);
  // Written back byte for byte.
  EXPECT_EQ(horus::TypeDescription::decode(description.encode()).encode(), description.encode());
}

// ---- Reading and writing
// ----------------------------------------------------------------------------

TEST(Params, DeclaredByANodeAndReadFromAnotherProcess) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  EXPECT_EQ(horus::param_nodes(), std::vector<std::string>{"motor"});
  Child reader("read", {"1.0"});
  EXPECT_EQ(reader.wait(), 0);
}

TEST(Params, SetWhileTickingCallsBackOnceOutsideAnyTickAndTheValueIsVisibleAfter) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([&] { return store_owned("motor") && motor->ticks > 3; }));
  const horus::ParamStoreReader reader("motor");
  const std::uint64_t seen = reader.change_count();
  Child setter("set", {"max_speed", "1.5"});
  ASSERT_EQ(setter.wait(), 0);
  EXPECT_EQ(motor->changes, 1);
  EXPECT_EQ(motor->overlaps.load(), 0);
  EXPECT_EQ(motor->max_speed.get(), 1.5);
  EXPECT_EQ(motor->max_speed.version(), 2U);
  EXPECT_EQ(horus_test::number_of(reader.get("max_speed").value), 1.5);
  EXPECT_EQ(reader.get("max_speed").version, 2U);
  EXPECT_GT(reader.wait_for_change(seen, std::chrono::seconds(1)), seen);
  {
    std::lock_guard lock(motor->mutex);
    EXPECT_EQ(motor->last_source, "horus param");
  }
  // Strings and arrays the same way.
  EXPECT_TRUE(horus::set_param("motor", "profile", packed(std::string("sport"))).accepted);
  EXPECT_TRUE(horus::set_param("motor", "gains", packed_list({0.1, 0.2, 0.3})).accepted);
  EXPECT_EQ(motor->profile.get(), "sport");
  EXPECT_EQ(motor->gains.get(), (std::array<double, 3>{0.1, 0.2, 0.3}));
  EXPECT_EQ(motor->changes, 3);
}

TEST(Params, ChangesNeverOverlapATickWhetherTheyArriveDuringOneOrBetweenTwo) {
  // Ticks of 2 ms at 200 Hz: writes land as often in a tick (they wait for its end) as while the
  // node's thread sleeps (the service calls the node itself).
  auto motor = std::make_shared<Motor>();
  motor->tick_sleep = std::chrono::milliseconds(2);
  Running running(motor);
  ASSERT_TRUE(eventually([&] { return store_owned("motor") && motor->ticks > 3; }));
  constexpr int kWrites = 200;
  for (int i = 0; i < kWrites; ++i) {
    ASSERT_TRUE(horus::set_param("motor", "retries", packed(i)).accepted) << i;
    std::this_thread::sleep_for(std::chrono::microseconds(100 + 37 * (i % 50)));
  }
  EXPECT_EQ(motor->changes.load(), kWrites);
  EXPECT_EQ(motor->overlaps.load(), 0);
  EXPECT_EQ(motor->retries.get(), kWrites - 1);
}

TEST(Params, WaitForChangeWakesOnAWrite) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  const horus::ParamStoreReader reader("motor");
  const std::uint64_t seen = reader.change_count();
  std::thread writer([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    horus::set_param("motor", "retries", packed(7));
  });
  const auto start = std::chrono::steady_clock::now();
  EXPECT_GT(reader.wait_for_change(seen, std::chrono::seconds(5)), seen);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(4));
  writer.join();
  EXPECT_EQ(motor->retries.get(), 7);
}

TEST(Params, OutOfRangeVetoedAndWrongValuesAreRefusedWithTheReasonAndChangeNothing) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  const auto unchanged = [&] {
    EXPECT_EQ(motor->max_speed.get(), 1.0);
    EXPECT_EQ(motor->max_speed.version(), 1U);
  };
  horus::ParamSetResult result = horus::set_param("motor", "max_speed", packed(2.5));
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("above the maximum 2"), std::string::npos) << result.reason;
  EXPECT_EQ(motor->changes, 0);  // the declaration refused it before the node was asked
  unchanged();

  result = horus::set_param("motor", "max_speed", packed(1.25));
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("1.25 is not a speed this motor likes"), std::string::npos)
      << result.reason;
  EXPECT_EQ(result.version, 1U);
  EXPECT_EQ(motor->changes, 1);
  unchanged();

  result = horus::set_param("motor", "profile", packed(std::string("turbo")));
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("not one of the allowed values"), std::string::npos);
  result = horus::set_param("motor", "wheel_count", packed(6));
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("read-only"), std::string::npos) << result.reason;
  result = horus::set_param("motor", "max_speed", packed(std::string("fast")));
  EXPECT_FALSE(result.accepted);
  EXPECT_NE(result.reason.find("expected a number"), std::string::npos) << result.reason;
  EXPECT_THROW(horus::set_param("motor", "max_sped", packed(1.0)), horus::ParamError);
  EXPECT_EQ(motor->wheel_count.get(), 4);
  unchanged();
}

TEST(Params, AMissingStoreNamesNodeAndNamespace) {
  try {
    horus::set_param("nobody", "x", packed(1.0));
    FAIL() << "no error";
  } catch (const horus::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("node 'nobody' (namespace 'params')"), std::string::npos)
        << e.what();
  }
}

TEST(Params, AWriteToAStoppedNodeIsRefusedOrPersistedForItsNextStart) {
  {
    auto motor = std::make_shared<Motor>();
    Running running(motor);
    ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  }
  const horus::ParamStoreReader reader("motor");
  EXPECT_FALSE(reader.owner_alive());
  horus::ParamSetResult result = horus::set_param("motor", "max_speed", packed(1.75));
  EXPECT_FALSE(result.accepted);
  EXPECT_EQ(result.reason, "node motor is not running");
  horus::ParamSetOptions persist;
  persist.persist = true;
  result = horus::set_param("motor", "max_speed", packed(1.75), persist);
  EXPECT_TRUE(result.accepted) << result.reason;
  EXPECT_EQ(horus_test::number_of(reader.get("max_speed").value), 1.0);  // not yet

  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  EXPECT_EQ(motor->max_speed.get(), 1.75);
  EXPECT_EQ(motor->max_speed.version(), 1U);
  // Kept for one start only.
  running.stop();
  auto again = std::make_shared<Motor>();
  Running next(again);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  EXPECT_EQ(again->max_speed.get(), 1.0);
}

TEST(Params, ASecondOwnerIsRefusedNamingTheFirst) {
  Child owner("own", {});
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  horus::Scheduler scheduler(real_time());
  scheduler.add(std::make_shared<Motor>()).build();
  try {
    scheduler.tick_once();
    FAIL() << "a second owner started";
  } catch (const horus::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(owner.pid())), std::string::npos)
        << e.what();
    // The child runs as /proc/self/exe: its program name is the kernel's for that.
    EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(owner.pid()) + " ("),
              std::string::npos)
        << e.what();
  }
}

TEST(Params, AKilledOwnersStoreIsTakenOverByTheNextStart) {
  {
    Child owner("own", {});
    ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
    owner.kill();
  }
  const horus::ParamStoreReader reader("motor");
  EXPECT_FALSE(reader.owner_alive());
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  EXPECT_TRUE(horus::set_param("motor", "retries", packed(9)).accepted);
  EXPECT_EQ(motor->retries.get(), 9);
  // The reader opened before the takeover sees it too (same store, reused in place).
  EXPECT_TRUE(reader.owner_alive());
  EXPECT_EQ(horus_test::number_of(reader.get("retries").value), 9);
}

TEST(Params, SigkilledWritersNeverLeaveATornOrInventedValue) {
  std::atomic<bool> reading{true};
  std::atomic<std::uint64_t> reads{0};
  std::atomic<int> bad{0};
  std::string bad_value;
  std::mutex bad_mutex;
  const auto check = [&](const std::string& text, const std::array<double, 3>& gains) {
    bool fine = (gains[0] == gains[1] && gains[1] == gains[2]) ||
                gains == std::array<double, 3>{1.0, 0.5, 0.0};  // the default
    if (text.empty() || text == "") {
    } else if (text[0] != 'v') {
      fine = false;
    } else {
      const std::size_t digits = text.find_first_not_of("0123456789", 1);
      const std::uint64_t n = std::stoull(text.substr(1, digits - 1));
      fine = fine && text == "v" + std::to_string(n) + std::string(40 + n % 100, 'a' + n % 26);
    }
    if (!fine) {
      bad.fetch_add(1);
      std::lock_guard lock(bad_mutex);
      bad_value = text + " / " + std::to_string(gains[0]) + "," + std::to_string(gains[1]) + "," +
                  std::to_string(gains[2]);
    }
  };
  std::mt19937 random(7);
  for (int round = 0; round < 12; ++round) {
    Child owner("frantic_owner", {std::to_string(round)});
    ASSERT_TRUE(eventually([] { return store_owned("motor"); })) << "round " << round;
    std::thread reader([&] {
      try {
        const horus::ParamStoreReader store("motor");
        while (reading.load()) {
          const std::string text = horus_test::text_of(store.get("label").value);
          const std::string gains = store.get("gains").value;
          const msgpack::object_handle handle = msgpack::unpack(gains.data(), gains.size());
          check(text, handle.get().as<std::array<double, 3>>());
          reads.fetch_add(1);
        }
      } catch (const std::exception& e) {
        bad.fetch_add(1);
        std::lock_guard lock(bad_mutex);
        bad_value = e.what();
      }
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(50 + random() % 150));
    owner.kill();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    reading = false;
    reader.join();
    reading = true;
  }
  EXPECT_EQ(bad.load(), 0) << bad_value;
  EXPECT_GT(reads.load(), 100U);
  // And the next start works, with the values it declares.
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  EXPECT_EQ(motor->label.get(), "");
  EXPECT_TRUE(horus::set_param("motor", "label", packed(std::string("fine"))).accepted);
  EXPECT_EQ(motor->label.get(), "fine");
}

// ---- YAML
// ----------------------------------------------------------------------------------------------

TEST(ParamFiles, DumpAndLoadRoundTrip) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  ASSERT_TRUE(horus::set_param("motor", "max_speed", packed(1.5)).accepted);
  ASSERT_TRUE(
      horus::set_param("motor", "label", packed(std::string("a \"quoted\": text"))).accepted);
  ASSERT_TRUE(horus::set_param("motor", "gains", packed_list({0.25, -1.0, 3.0})).accepted);
  const std::string dumped = horus::dump_param_file();
  EXPECT_NE(dumped.find("motor:\n  max_speed: 1.5\n"), std::string::npos) << dumped;
  EXPECT_NE(dumped.find("  gains: [0.25, -1.0, 3.0]\n"), std::string::npos) << dumped;
  const std::string path = write_file("robot.yaml", dumped);

  ASSERT_TRUE(horus::set_param("motor", "max_speed", packed(0.5)).accepted);
  ASSERT_TRUE(horus::set_param("motor", "label", packed(std::string("other"))).accepted);
  ASSERT_TRUE(horus::set_param("motor", "gains", packed_list({0, 0, 0})).accepted);
  // The read-only value is written too, and refused while the node runs.
  const std::vector<horus::ParamSetResult> results = horus::load_param_file(path);
  EXPECT_EQ(results.size(), 7U);
  EXPECT_EQ(motor->max_speed.get(), 1.5);
  EXPECT_EQ(motor->label.get(), "a \"quoted\": text");
  EXPECT_EQ(motor->gains.get(), (std::array<double, 3>{0.25, -1.0, 3.0}));
  EXPECT_EQ(horus::dump_param_file({"motor"}), dumped);
  {
    std::lock_guard lock(motor->mutex);
    EXPECT_EQ(motor->last_source, "yaml:" + path);
  }
}

TEST(ParamFiles, ErrorsNameFileAndLineAndNothingIsWritten) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  const std::string path = write_file("bad.yaml",
                                      "# comment\n"
                                      "motor:\n"
                                      "  retries: 5\n"
                                      "  max_speed: 9.0\n"
                                      "  max_sped: 1.0\n"
                                      "  gains: [1.0, 2.0]\n"
                                      "ghost:\n"
                                      "  x: 1\n");
  try {
    horus::load_param_file(path);
    FAIL() << "no error";
  } catch (const horus::ParamError& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find(path + ":4: motor.max_speed: 9 is above the maximum 2"), std::string::npos)
        << text;
    EXPECT_NE(text.find(path + ":5: node 'motor' has no parameter 'max_sped'"), std::string::npos)
        << text;
    EXPECT_NE(text.find(path + ":6: motor.gains: expected 3 elements"), std::string::npos) << text;
    EXPECT_NE(text.find(path + ":7: node 'ghost'"), std::string::npos) << text;
  }
  EXPECT_EQ(motor->retries.get(), 3);  // the good line was not applied either
  EXPECT_EQ(motor->changes, 0);

  const std::string broken = write_file("broken.yaml", "motor:\n  retries: [1, 2\n");
  try {
    horus::load_param_file(broken);
    FAIL() << "no error";
  } catch (const horus::ParamError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(broken + ":", 0), 0U) << e.what();
  }
}

TEST(ParamFiles, TheSchedulerStartsWithTheFileAndRefusesABadOne) {
  const std::string good = write_file("good.yaml", "motor:\n  max_speed: 0.75\n  wheel_count: 6\n");
  {
    auto motor = std::make_shared<Motor>();
    horus::Scheduler scheduler(real_time().params(good));
    scheduler.add(motor).build();
    scheduler.tick_once();
    EXPECT_EQ(motor->max_speed.get(), 0.75);
    EXPECT_EQ(motor->wheel_count.get(), 6);  // read-only: a file at start may set it
    EXPECT_EQ(motor->max_speed.version(), 1U);
  }
  const std::string bad =
      write_file("start.yaml", "motor:\n  max_speed: 0.75\n  profile: turbo\nbrake:\n  x: 1\n");
  auto motor = std::make_shared<Motor>();
  horus::Scheduler scheduler(real_time().params(bad));
  scheduler.add(motor).build();
  try {
    scheduler.tick_once();
    FAIL() << "started with a bad parameter file";
  } catch (const horus::ParamError& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find(bad + ":3: motor.profile: not one of the allowed values"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find(bad + ":4: no node 'brake'"), std::string::npos) << text;
  }
  EXPECT_EQ(motor->ticks, 0);
}

// ---- Shared memory
// ---------------------------------------------------------------------------------

TEST(ParamStores, ShmListShowsThemAndCleanRemovesThoseWithoutAnOwner) {
  const auto stores = [] {
    std::vector<horus::NamespaceObjectInfo> found;
    for (horus::NamespaceObjectInfo& object : horus::list_namespace_objects()) {
      if (object.kind == "@params") found.push_back(object);
    }
    return found;
  };
  auto motor = std::make_shared<Motor>();
  auto running = std::make_unique<Running>(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  ASSERT_EQ(stores().size(), 1U);
  EXPECT_TRUE(stores()[0].in_use);
  EXPECT_NE(stores()[0].path.find("@params/params/motor"), std::string::npos);
  horus::clean_namespace();
  EXPECT_EQ(stores().size(), 1U);
  EXPECT_TRUE(store_owned("motor"));
  running.reset();
  ASSERT_EQ(stores().size(), 1U);
  EXPECT_FALSE(stores()[0].in_use);
  horus::clean_namespace();
  EXPECT_TRUE(stores().empty());
  EXPECT_TRUE(horus::param_nodes().empty());
}

TEST(ParamStores, AForeignFileIsAnErrorNotACrash) {
  const std::string folder = shm_root + "/@params/params";
  std::filesystem::create_directories(folder);
  std::filesystem::permissions(shm_root + "/@params", std::filesystem::perms::owner_all);
  std::filesystem::permissions(folder, std::filesystem::perms::owner_all);
  for (const std::string& content : {std::string("short"), std::string(4096, 'x'),
                                     std::string("horusprm") + std::string(200, '\xff')}) {
    {
      std::ofstream out(folder + "/junk", std::ios::binary | std::ios::trunc);
      out << content;
    }
    std::filesystem::permissions(
        folder + "/junk", std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    EXPECT_THROW(horus::ParamStoreReader("junk"), horus::Error);
  }
  // A node named so takes the foreign file over.
  auto motor = std::make_shared<Motor>("junk");
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("junk"); }));
  EXPECT_EQ(horus::ParamStoreReader("junk").list().size(), 7U);
}

TEST(ParamStores, NodeNamesOutsideTheTopicCharactersAreRefused) {
  auto motor = std::make_shared<Motor>("motor<left>");
  horus::Scheduler scheduler(real_time());
  scheduler.add(motor).build();
  try {
    scheduler.tick_once();
    FAIL() << "no error";
  } catch (const horus::ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("[A-Za-z0-9_.-]"), std::string::npos) << e.what();
  }
  EXPECT_THROW(horus::ParamStoreReader("../etc"), horus::ParamError);
}

TEST(ParamReads, AScalarReadIsOneAtomicLoad) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  constexpr int kReads = 10'000'000;
  double sum = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < kReads; ++i) sum += motor->max_speed.get();
  const auto elapsed = std::chrono::steady_clock::now() - start;
  const double ns = std::chrono::duration<double, std::nano>(elapsed).count() / kReads;
  std::printf("Param<double>::get(): %.2f ns per read (sum %.0f)\n", ns, sum);
  EXPECT_EQ(sum, kReads * 1.0);
}

TEST(ParamReads, AReaderGetsTypedHandlesThatFollowTheOwnersWrites) {
  auto motor = std::make_shared<Motor>();
  Running running(motor);
  ASSERT_TRUE(eventually([] { return store_owned("motor"); }));
  const horus::ParamStoreReader store("motor");
  const horus::Param<double> max_speed = store.param<double>("max_speed");
  const horus::Param<std::string> profile = store.param<std::string>("profile");
  const horus::Param<std::array<double, 3>> gains = store.param<std::array<double, 3>>("gains");
  EXPECT_EQ(max_speed.get(), 1.0);
  EXPECT_EQ(profile.get(), "eco");
  EXPECT_EQ(gains.get(), (std::array<double, 3>{1.0, 0.5, 0.0}));
  const std::uint64_t version = max_speed.version();
  ASSERT_TRUE(horus::set_param("motor", "max_speed", packed(1.5)).accepted);
  ASSERT_TRUE(horus::set_param("motor", "profile", packed(std::string("sport"))).accepted);
  EXPECT_EQ(max_speed.get(), 1.5);
  EXPECT_EQ(max_speed.version(), version + 1);
  EXPECT_EQ(profile.get(), "sport");
  EXPECT_THROW(store.param<float>("max_speed"), horus::ParamError);
  EXPECT_THROW(store.param<double>("top_speed"), horus::ParamError);
}
