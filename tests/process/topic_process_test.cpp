// Topics between real processes: the test binary re-executes itself to play publishers and
// subscribers (see topic_test_support.hpp). Every wait is bounded, so a failure never hangs.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/audit.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <horus/detail/process.hpp>
#include <horus/detail/shm_segment.hpp>
#include <horus/internal/topic_notifier.hpp>
#include <horus/internal/topic_wait_set.hpp>
#include <horus/msg/generic_message.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_test/big.hpp>
#include <topic_test/blob.hpp>
#include <topic_test/other.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using topic_test::Big;
using topic_test::Blob;
using topic_test::Child;
using topic_test::Other;
using topic_test::PrivateNamespace;
using topic_test::Sample;
using topic_test::sealed;
using topic_test::valid;

/// A handle on a topic's control page only, for looking at its ring and users table.
horus::detail::ShmSegment control_page(const std::string& topic) {
  return horus::detail::ShmSegment::open_control(topic, {0, 0, 0600, {}, false});
}

constexpr auto kDeadline = 30s;

bool past(std::chrono::steady_clock::time_point deadline) {
  return std::chrono::steady_clock::now() > deadline;
}

/// Per-publisher counts a subscriber reports back, packed into an ack Sample's payload.
void put_count(Sample& ack, std::size_t publisher, std::uint64_t count) {
  std::memcpy(ack.payload.data() + publisher * 8, &count, 8);
}
std::uint64_t get_count(const Sample& ack, std::size_t publisher) {
  std::uint64_t count = 0;
  std::memcpy(&count, ack.payload.data() + publisher * 8, 8);
  return count;
}

// ---- Roles -------------------------------------------------------------------------------------

/// publish <topic> <publisher id> <count> <subscribers> <window> [capacity]: sends `count`
/// sealed Samples (salt = publisher id), never more than `window` ahead of any subscriber's ack.
int role_publish(const std::vector<std::string>& args) {
  const std::string topic = args.at(0);
  const std::size_t id = std::stoul(args.at(1));
  const std::uint64_t count = std::stoull(args.at(2));
  const std::size_t subscribers = std::stoul(args.at(3));
  const std::uint64_t window = std::stoull(args.at(4));
  horus::TopicOptions options;
  options.capacity = args.size() > 5 ? std::stoul(args.at(5)) : 64;
  horus::Topic<Sample> data(topic, options);
  std::vector<horus::Topic<Sample>> acks;
  for (std::size_t k = 0; k < subscribers; ++k) {
    acks.emplace_back(topic + ".ack" + std::to_string(k));
  }
  const auto deadline = std::chrono::steady_clock::now() + kDeadline;
  std::vector<std::uint64_t> acked(subscribers, 0);
  auto refresh = [&](bool sleep) {
    for (std::size_t k = 0; k < subscribers; ++k) {
      if (auto latest = acks[k].read_latest()) {
        acked[k] = std::max(acked[k], get_count(*latest, id));
      }
    }
    if (sleep) {
      acks[0].recv(1ms);
    }
  };
  // Every subscriber announces itself (count 0) once its handle is open.
  for (std::size_t k = 0; k < subscribers; ++k) {
    while (!acks[k].read_latest()) {
      if (past(deadline)) {
        std::fprintf(stderr, "publisher %zu: subscriber %zu never became ready\n", id, k);
        return 10;
      }
      acks[k].recv(1ms);
    }
  }
  for (std::uint64_t i = 0; i < count; ++i) {
    for (;;) {
      std::uint64_t slowest = UINT64_MAX;
      for (const std::uint64_t a : acked) {
        slowest = std::min(slowest, a);
      }
      if (i - std::min(i, slowest) < window) {
        break;
      }
      if (past(deadline)) {
        std::fprintf(stderr, "publisher %zu: stuck at %llu\n", id,
                     static_cast<unsigned long long>(i));
        return 11;
      }
      refresh(true);
    }
    if (!data.send(sealed<Sample>(i, id))) {
      std::fprintf(stderr, "publisher %zu: send %llu failed\n", id,
                   static_cast<unsigned long long>(i));
      return 12;
    }
    if (i % 64 == 0) {
      refresh(false);
    }
  }
  return 0;
}

/// subscribe <topic> <subscriber id> <publishers> <count each>: expects every publisher's
/// messages in order, none lost, each sealed; acks progress every 256 messages and when idle.
int role_subscribe(const std::vector<std::string>& args) {
  const std::string topic = args.at(0);
  const std::size_t id = std::stoul(args.at(1));
  const std::size_t publishers = std::stoul(args.at(2));
  const std::uint64_t count = std::stoull(args.at(3));
  horus::Topic<Sample> data(topic);
  horus::Topic<Sample> ack(topic + ".ack" + std::to_string(id));
  std::vector<std::uint64_t> next(publishers, 0);
  Sample progress{};
  ack.send(progress);
  const auto deadline = std::chrono::steady_clock::now() + kDeadline;
  std::uint64_t total = 0;
  auto report = [&] {
    for (std::size_t p = 0; p < publishers; ++p) {
      put_count(progress, p, next[p]);
    }
    ack.send(progress);
  };
  while (total < count * publishers) {
    auto msg = data.try_recv();
    if (!msg) {
      // Caught up: tell the publishers before sleeping, so none waits on a stale ack.
      report();
      msg = data.recv(100ms);
    }
    if (!msg) {
      if (past(deadline)) {
        std::fprintf(stderr, "subscriber %zu: timed out after %llu messages\n", id,
                     static_cast<unsigned long long>(total));
        return 20;
      }
      continue;
    }
    std::size_t from = publishers;
    for (std::size_t p = 0; p < publishers; ++p) {
      if (msg->seq == next[p] && *msg == sealed<Sample>(msg->seq, p)) {
        from = p;
        break;
      }
    }
    if (from == publishers) {
      std::fprintf(stderr, "subscriber %zu: unexpected message seq %llu (valid %d)\n", id,
                   static_cast<unsigned long long>(msg->seq), valid(*msg) ? 1 : 0);
      return 21;
    }
    ++next[from];
    ++total;
    if (total % 256 == 0) {
      report();
    }
  }
  if (data.lost() != 0) {
    std::fprintf(stderr, "subscriber %zu: lost %llu\n", id,
                 static_cast<unsigned long long>(data.lost()));
    return 22;
  }
  return 0;
}

/// send_plain <topic> <first seq> <count> [capacity]: sends without flow control, then exits.
int role_send_plain(const std::vector<std::string>& args) {
  horus::TopicOptions options;
  options.capacity = args.size() > 3 ? std::stoul(args.at(3)) : 64;
  horus::Topic<Sample> data(args.at(0), options);
  const std::uint64_t first = std::stoull(args.at(1));
  const std::uint64_t count = std::stoull(args.at(2));
  for (std::uint64_t i = first; i < first + count; ++i) {
    if (!data.send(sealed<Sample>(i))) {
      return 30;
    }
  }
  return 0;
}

/// stream_big <topic> <first seq>: sends sealed Bigs until killed; exits 35 if a send fails.
int role_stream_big(const std::vector<std::string>& args) {
  horus::Topic<Big> data(args.at(0), {.capacity = 16});
  for (std::uint64_t i = std::stoull(args.at(1));; ++i) {
    if (!data.send(sealed<Big>(i))) {
      return 35;
    }
  }
}

/// hold_loan <topic>: takes a loan, half-writes it, announces it on <topic>.held and waits to be
/// killed while the slot is still marked as being written.
int role_hold_loan(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  horus::Topic<Sample> held(args.at(0) + ".held");
  auto loan = data.loan();
  loan->seq = 424242;
  held.send(sealed<Sample>(1));
  std::this_thread::sleep_for(kDeadline);
  return 40;
}

/// echo <topic>: replies every Sample on <topic>.reply until it sees seq == UINT64_MAX.
int role_echo(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  horus::Topic<Sample> reply(args.at(0) + ".reply");
  reply.send(sealed<Sample>(0));
  const auto deadline = std::chrono::steady_clock::now() + kDeadline;
  while (!past(deadline)) {
    if (auto msg = data.recv(100ms)) {
      if (msg->seq == UINT64_MAX) {
        return 0;
      }
      reply.send(*msg);
    }
  }
  return 50;
}

/// open_and_exit <topic>: opens a Sample topic and exits (leaving a segment with no live user).
int role_open_and_exit(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  data.send(sealed<Sample>(7));
  return 0;
}

/// send_blobs <topic> <count>: serialized messages of growing size, one oversized in between.
int role_send_blobs(const std::vector<std::string>& args) {
  horus::Topic<Blob> data(args.at(0), {.capacity = 64, .max_message_size = 2048});
  const std::uint64_t count = std::stoull(args.at(1));
  for (std::uint64_t i = 0; i < count; ++i) {
    Blob blob;
    blob.seq = i;
    blob.text = std::string(i % 50, 'a' + static_cast<char>(i % 26));
    blob.data.assign(i * 7 % 1500, static_cast<std::uint8_t>(i));
    if (i % 3 == 0) {
      blob.note = "note " + std::to_string(i);
    }
    if (!data.send(blob)) {
      return 60;
    }
    if (i == count / 2) {
      Blob huge;
      huge.data.assign(4096, 1);
      if (data.send(huge) || data.stats().oversized != 1) {
        return 61;
      }
    }
  }
  return 0;
}

/// A reading as a prototype would send it in a GenericMessage: a map of names to numbers.
using Reading = std::map<std::string, double>;

Reading reading(std::uint64_t i) {
  return {{"seq", static_cast<double>(i)}, {"volts", 11.5 + static_cast<double>(i) / 8}};
}

/// send_generic <topic> <count>: GenericMessages packed from a map, every other one with metadata.
int role_send_generic(const std::vector<std::string>& args) {
  horus::Topic<horus::msg::GenericMessage> data(args.at(0));
  const std::uint64_t count = std::stoull(args.at(1));
  for (std::uint64_t i = 0; i < count; ++i) {
    horus::msg::GenericMessage msg = horus::msg::GenericMessage::from_value(reading(i));
    if (i % 2 == 1) {
      msg.metadata = "battery " + std::to_string(i);
    }
    if (!data.send(msg)) {
      return 62;
    }
  }
  return 0;
}

/// send_values <topic> <count>: u64 counters, and their triples as [f32; 3] on <topic>.xyz.
int role_send_values(const std::vector<std::string>& args) {
  horus::Topic<std::uint64_t> counters(args.at(0));
  horus::Topic<std::array<float, 3>> triples(args.at(0) + ".xyz");
  const std::uint64_t count = std::stoull(args.at(1));
  for (std::uint64_t i = 0; i < count; ++i) {
    const auto x = static_cast<float>(i);
    if (!counters.send(i * 0x0101010101010101ULL) || !triples.send({x, x / 2, -x})) {
      return 63;
    }
  }
  return 0;
}

/// no_room <topic>: with a 1 MiB file size limit, creating a 16 MiB topic must be a clear error.
int role_no_room(const std::vector<std::string>& args) {
  ::signal(SIGXFSZ, SIG_IGN);
  const rlimit limit{1 << 20, 1 << 20};
  ::setrlimit(RLIMIT_FSIZE, &limit);
  try {
    horus::Topic<Big> data(args.at(0), {.capacity = 4096});
  } catch (const horus::Error& e) {
    const std::string text = e.what();
    return text.find("cannot allocate") != std::string::npos &&
                   text.find(args.at(0)) != std::string::npos
               ? 0
               : 71;
  }
  return 70;
}

/// send_after <topic> <delay ms>: sleeps, then sends one Sample.
int role_send_after(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  std::this_thread::sleep_for(std::chrono::milliseconds(std::stoul(args.at(1))));
  return data.send(sealed<Sample>(5)) ? 0 : 80;
}

/// send_and_hold <topic> <count>: sends `count` sealed Samples from 0, announces them on
/// <topic>.held and waits to be killed, still holding a single-publisher topic's lease.
int role_send_and_hold(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  horus::Topic<Sample> held(args.at(0) + ".held");
  for (std::uint64_t i = 0; i < std::stoull(args.at(1)); ++i) {
    if (!data.send(sealed<Sample>(i))) {
      return 37;
    }
  }
  held.send(sealed<Sample>(1));
  std::this_thread::sleep_for(kDeadline);
  return 38;
}

/// sleep_in_recv <topic>: waits in recv() until killed; exits 39 if anything arrives.
int role_sleep_in_recv(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  return data.recv(kDeadline).has_value() ? 39 : 40;
}

/// Whether a lease holder skips its own barrier and relies on membarrier(2): not in
/// ThreadSanitizer builds (publisher_lease.cpp), where a second publisher is never refused.
#if defined(__SANITIZE_THREAD__)
constexpr bool kHolderReliesOnMembarrier = false;
#else
constexpr bool kHolderReliesOnMembarrier = true;
#endif

/// Makes membarrier(2) fail with EPERM in this process, as a sandbox or an old kernel would.
bool forbid_membarrier() {
  sock_filter filter[] = {
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, AUDIT_ARCH_X86_64, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, SYS_membarrier, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
  };
  sock_fprog program{static_cast<unsigned short>(std::size(filter)), filter};
  return ::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) == 0 &&
         ::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &program) == 0 &&
         ::syscall(SYS_membarrier, 0, 0, 0) != 0;
}

/// send_without_membarrier <topic>: with membarrier forbidden, sends one Sample (seq 99) as a
/// second publisher, retrying for 20 s; says on <topic>.refused when its first send is refused (the
/// test lets the holder go only then); 0 once a send got through after that refusal.
int role_send_without_membarrier(const std::vector<std::string>& args) {
  if (!forbid_membarrier()) {
    return 41;
  }
  horus::Topic<Sample> data(args.at(0));
  horus::Topic<Sample> refused(args.at(0) + ".refused");
  bool told = false;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (!data.send(sealed<Sample>(99))) {
    told = told || refused.send(sealed<Sample>(0));
    if (past(deadline)) {
      return 42;
    }
    std::this_thread::sleep_for(1ms);
  }
  return told || !kHolderReliesOnMembarrier ? 0 : 43;
}

/// try_send <topic>: one send; exits 0 if it was refused as not the publisher, 36 otherwise.
int role_try_send(const std::vector<std::string>& args) {
  horus::Topic<Sample> data(args.at(0));
  const bool sent = data.send(sealed<Sample>(77));
  return !sent && data.stats().not_the_publisher == 1 ? 0 : 36;
}

const bool kRolesRegistered = [] {
  auto& roles = topic_test::roles();
  roles["publish"] = role_publish;
  roles["subscribe"] = role_subscribe;
  roles["send_plain"] = role_send_plain;
  roles["stream_big"] = role_stream_big;
  roles["hold_loan"] = role_hold_loan;
  roles["echo"] = role_echo;
  roles["open_and_exit"] = role_open_and_exit;
  roles["send_blobs"] = role_send_blobs;
  roles["send_generic"] = role_send_generic;
  roles["send_values"] = role_send_values;
  roles["no_room"] = role_no_room;
  roles["send_after"] = role_send_after;
  roles["try_send"] = role_try_send;
  roles["send_without_membarrier"] = role_send_without_membarrier;
  roles["send_and_hold"] = role_send_and_hold;
  roles["sleep_in_recv"] = role_sleep_in_recv;
  return true;
}();
// Runs before main: a re-executed child plays its role and exits here.
const int kRoleStatus = topic_test::dispatch_role();

// ---- Tests -------------------------------------------------------------------------------------

/// Who sends to a subscriber: the topic's first publisher (the lease holder), a second one (the
/// ring is shared), or the holder of a single-publisher topic.
enum class Sender { first, second, single };

void million_messages(Sender who) {
  PrivateNamespace ns;
  horus::Topic<Sample> create("million",
                              {.capacity = 1024, .single_publisher = who == Sender::single});
  if (who == Sender::second) {
    // Before the subscriber opens, so it never sees this one.
    ASSERT_TRUE(create.send(sealed<Sample>(0, 9)));
  }
  Child subscriber("subscribe", {"million", "0", "1", "1000000"});
  Child publisher("publish", {"million", "0", "1000000", "1", "768"});
  EXPECT_EQ(publisher.wait(), 0);
  EXPECT_EQ(subscriber.wait(), 0);
  const auto control = control_page("million");
  EXPECT_EQ(horus::detail::ring_shared_base(control.control().ring) != horus::detail::kUnshared,
            who == Sender::second)
      << "the ring is shared exactly when a second publisher sent";
}

// The subscriber also sleeps in recv() whenever it catches up: while one publisher holds the
// lease, every wake-up relies on the sleepers' membarrier, as it takes no barrier of its own.
TEST(TopicProcess, MillionMessagesArriveInOrderWithoutLoss) { million_messages(Sender::first); }

TEST(TopicProcess, MillionMessagesThroughASharedRingArriveInOrderWithoutLoss) {
  million_messages(Sender::second);
}

TEST(TopicProcess, MillionMessagesFromASinglePublisherArriveInOrderWithoutLoss) {
  million_messages(Sender::single);
}

TEST(TopicProcess, SinglePublisherLeaseRefusesOthersUntilItsHolderDies) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("solo", {.capacity = 16, .single_publisher = true});
  horus::Topic<Sample> held("solo.held");
  Child holder("send_and_hold", {"solo", "5"});
  ASSERT_TRUE(held.recv(10s).has_value()) << "the holder never came up";
  Child refused("try_send", {"solo"});
  EXPECT_EQ(refused.wait(), 0) << "another process published beside the lease holder";
  EXPECT_FALSE(data.send(sealed<Sample>(50)));
  EXPECT_EQ(data.stats().not_the_publisher, 1u);

  holder.kill();
  Child successor("send_plain", {"solo", "100", "3"});
  EXPECT_EQ(successor.wait(), 0) << "the dead holder's lease was not taken over";
  std::vector<std::uint64_t> got;
  while (auto msg = data.try_recv()) {
    EXPECT_TRUE(valid(*msg));
    got.push_back(msg->seq);
  }
  EXPECT_EQ(got, (std::vector<std::uint64_t>{0, 1, 2, 3, 4, 100, 101, 102}));
  EXPECT_EQ(data.lost(), 0u);
}

TEST(TopicProcess, AForkedChildDoesNotPublishUnderItsParentsLease) {
  PrivateNamespace ns;
  horus::Topic<Sample> publisher("forked", {.capacity = 16, .single_publisher = true});
  horus::Topic<Sample> subscriber("forked");
  ASSERT_TRUE(publisher.send(sealed<Sample>(1)));
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The inherited handle is a copy of one that holds the lease, in another process.
    const bool refused = !publisher.send(sealed<Sample>(99));
    ::_exit(refused && publisher.stats().not_the_publisher == 1 ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << "the forked child published beside its parent";
  EXPECT_TRUE(publisher.send(sealed<Sample>(2))) << "the parent lost its lease";
  std::vector<std::uint64_t> got;
  while (auto msg = subscriber.try_recv()) {
    EXPECT_TRUE(valid(*msg));
    got.push_back(msg->seq);
  }
  EXPECT_EQ(got, (std::vector<std::uint64_t>{1, 2}));
}

/// Sleepers announced on a topic (the high bits of its write index), read through a control-page
/// handle of its own.
std::uint64_t announced_sleepers(const horus::detail::ShmSegment& segment) {
  return segment.control().ring.write_index.load() >> 56;
}

bool wait_for_sleepers(const horus::detail::ShmSegment& segment, std::uint64_t count) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (announced_sleepers(segment) != count) {
    if (std::chrono::steady_clock::now() > deadline) {
      return false;
    }
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

TEST(TopicProcess, AForkedChildLettingGoOfAnInheritedHandleLeavesItsParentsEntry) {
  PrivateNamespace ns;
  std::optional<horus::Topic<Sample>> publisher(std::in_place, "inherited");
  ASSERT_TRUE(publisher->send(sealed<Sample>(1)));
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    publisher.reset();
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].publishers, 1u) << "the child freed its parent's entry";
}

/// A topic whose subscriber, another process, was killed while asleep in recv(): its sleeper
/// announcement is still counted.
class TopicProcessWithASubscriberKilledAsleep : public ::testing::Test {
 protected:
  void SetUp() override {
    Child sleeper("sleep_in_recv", {"asleep"});
    ASSERT_TRUE(wait_for_sleepers(control_, 1)) << "the child never went to sleep";
    sleeper_pid_ = sleeper.pid();
    sleeper.kill();
  }

  PrivateNamespace ns_;
  horus::Topic<Sample> data_{"asleep", {.capacity = 16}};
  horus::detail::ShmSegment control_ = control_page("asleep");
  pid_t sleeper_pid_ = -1;
};

TEST_F(TopicProcessWithASubscriberKilledAsleep, ItsAnnouncementIsGivenBackByTheNextSend) {
  EXPECT_EQ(announced_sleepers(control_), 1u) << "a dead sleeper's announcement stays";

  // This send's wake finds nobody, so it looks for dead sleepers and gives theirs back: later
  // sends make no syscall.
  EXPECT_TRUE(data_.send(sealed<Sample>(1)));
  EXPECT_EQ(announced_sleepers(control_), 0u);

  // A live sleeper is left alone, and woken.
  std::optional<Sample> woken;
  std::thread waiter([&] {
    horus::Topic<Sample> own("asleep");
    woken = own.recv(10s);
  });
  ASSERT_TRUE(wait_for_sleepers(control_, 1));
  horus::detail::ring_reclaim_dead_sleepers(control_.ring());
  EXPECT_EQ(announced_sleepers(control_), 1u) << "a live sleeper's announcement was taken";
  EXPECT_TRUE(data_.send(sealed<Sample>(2)));
  waiter.join();
  ASSERT_TRUE(woken.has_value());
  EXPECT_EQ(woken->seq, 2u);
  EXPECT_EQ(announced_sleepers(control_), 0u);
}

TEST(TopicProcess, AForkedChildKilledAsleepOnAnInheritedHandleIsGivenBack) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("forked_asleep", {.capacity = 16});
  const auto control = control_page("forked_asleep");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    static_cast<void>(data.recv(30s));
    ::_exit(0);
  }
  const bool slept = wait_for_sleepers(control, 1);
  ::kill(child, SIGKILL);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  ASSERT_TRUE(slept) << "the child never went to sleep";

  EXPECT_TRUE(data.send(sealed<Sample>(1)));
  EXPECT_EQ(announced_sleepers(control), 0u)
      << "the child's announcement was counted in its live parent's entry";
  EXPECT_EQ(data.try_recv()->seq, 1u) << "the parent's handle no longer works";
}

/// The entry of the users table that names process `pid`, or nullptr.
horus::detail::UserEntry* entry_of(const horus::detail::ShmSegment& segment, pid_t pid) {
  for (horus::detail::UserEntry& user : segment.control().users) {
    if (horus::detail::identity_pid(user.process.load()) == static_cast<std::uint32_t>(pid)) {
      return &user;
    }
  }
  return nullptr;
}

/// Makes a dead process's entry look as it does once the kernel has given its pid to another
/// process: the pid of a live one (this test's parent, which started long before it), its own
/// start time.
void give_its_pid_to_a_live_process(horus::detail::UserEntry& user) {
  const std::uint64_t dead = user.process.load();
  ASSERT_NE(dead >> 32, 0u) << "the dead process's start time was not recorded";
  user.process.store((dead & ~std::uint64_t{0xffffffff}) | static_cast<std::uint32_t>(::getppid()));
}

TEST_F(TopicProcessWithASubscriberKilledAsleep, ItsAnnouncementIsGivenBackEvenOnceItsPidIsReused) {
  horus::detail::UserEntry* entry = entry_of(control_, sleeper_pid_);
  ASSERT_NE(entry, nullptr);
  ASSERT_NO_FATAL_FAILURE(give_its_pid_to_a_live_process(*entry));

  EXPECT_TRUE(data_.send(sealed<Sample>(1)));
  EXPECT_EQ(announced_sleepers(control_), 0u)
      << "a dead sleeper whose pid a live process has now was taken for alive";
  EXPECT_EQ(entry->process.load(), 0u) << "its entry was not freed";
}

TEST(TopicProcess, EntriesOfDeadProcessesWithReusedPidsAreNeitherCountedNorInTheWay) {
  PrivateNamespace ns;
  { horus::Topic<Sample> placeholder("crowded"); }
  const auto control = control_page("crowded");
  // Every entry but the control handle's own names this process with a start time it never had:
  // the state a table is left in when its users were killed and their pids went to live ones.
  const std::uint64_t wrong_start =
      std::uint64_t{0xfffffffe} << 32 | static_cast<std::uint32_t>(::getpid());
  for (horus::detail::UserEntry& user : control.control().users) {
    if (user.process.load() == 0) {
      user.roles.store(horus::detail::kRolePublisher | horus::detail::kRoleSubscriber);
      user.process.store(wrong_start);
    }
  }
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].publishers, 0u);
  EXPECT_EQ(topics[0].subscribers, 0u);

  std::optional<horus::Topic<Sample>> opened;
  EXPECT_NO_THROW(opened.emplace("crowded")) << "the dead entries were taken for live handles";
}

// The first publisher to send holds the lease until the others share the ring, mid-stream.
TEST(TopicProcess, SeveralPublishersAndSubscribersEachSeeEverything) {
  PrivateNamespace ns;
  horus::Topic<Sample> create("many", {.capacity = 512});
  std::vector<std::unique_ptr<Child>> children;
  for (int s = 0; s < 2; ++s) {
    children.push_back(std::make_unique<Child>(
        "subscribe", std::vector<std::string>{"many", std::to_string(s), "3", "20000"}));
  }
  for (int p = 0; p < 3; ++p) {
    children.push_back(std::make_unique<Child>(
        "publish", std::vector<std::string>{"many", std::to_string(p), "20000", "2", "128"}));
  }
  for (auto& child : children) {
    EXPECT_EQ(child->wait(), 0);
  }
}

TEST(TopicProcess, LaggingSubscriberLosesTheOldestAndCountsThem) {
  PrivateNamespace ns;
  horus::Topic<Sample> slow("lag", {.capacity = 64});
  Child publisher("send_plain", {"lag", "0", "1000"});
  ASSERT_EQ(publisher.wait(), 0);
  std::vector<std::uint64_t> got;
  while (auto msg = slow.try_recv()) {
    EXPECT_TRUE(valid(*msg));
    got.push_back(msg->seq);
  }
  ASSERT_EQ(got.size(), 64u);
  EXPECT_EQ(slow.lost(), 1000u - 64u);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i], 1000u - 64u + i);
  }
}

TEST(TopicProcess, LateJoinerSeesOnlyNewMessagesButReadLatestSeesTheNewest) {
  PrivateNamespace ns;
  {
    Child publisher("send_plain", {"late", "0", "10"});
    ASSERT_EQ(publisher.wait(), 0);
  }
  horus::Topic<Sample> late("late");
  EXPECT_FALSE(late.has_msg());
  EXPECT_FALSE(late.try_recv().has_value());
  auto latest = late.read_latest();
  ASSERT_TRUE(latest.has_value());
  EXPECT_EQ(latest->seq, 9u);
  EXPECT_TRUE(valid(*latest));
  Child more("send_plain", {"late", "10", "1"});
  ASSERT_EQ(more.wait(), 0);
  auto next = late.try_recv();
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->seq, 10u);
  EXPECT_EQ(late.lost(), 0u);
}

TEST(TopicProcess, AnotherTypeIsRefusedAndTheIncumbentsKeepWorking) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("typed");
  horus::Topic<Sample> reply("typed.reply");
  Child echo("echo", {"typed"});
  ASSERT_TRUE(reply.recv(10s).has_value()) << "the echo child never came up";

  try {
    horus::Topic<Other> wrong("typed");
    FAIL() << "opening a Sample topic as Other succeeded";
  } catch (const horus::Error& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find("topic_test.Sample"), std::string::npos) << text;
    EXPECT_NE(text.find("topic_test.Other"), std::string::npos) << text;
    char fingerprint[32];
    std::snprintf(fingerprint, sizeof fingerprint, "%016llx",
                  static_cast<unsigned long long>(horus::TypeInfo<Sample>::fingerprint));
    EXPECT_NE(text.find(fingerprint), std::string::npos) << text;
    std::snprintf(fingerprint, sizeof fingerprint, "%016llx",
                  static_cast<unsigned long long>(horus::TypeInfo<Other>::fingerprint));
    EXPECT_NE(text.find(fingerprint), std::string::npos) << text;
    // Who still uses the old type: the echo child, with its program's name as the kernel has it.
    const std::string echo_name =
        horus::detail::process_name(static_cast<std::uint32_t>(echo.pid()));
    ASSERT_FALSE(echo_name.empty());
    EXPECT_NE(text.find("pid " + std::to_string(echo.pid()) + " (" + echo_name + ")"),
              std::string::npos)
        << text;
  }

  ASSERT_TRUE(data.send(sealed<Sample>(33)));
  auto echoed = reply.recv(10s);
  ASSERT_TRUE(echoed.has_value());
  EXPECT_EQ(*echoed, sealed<Sample>(33));
  data.send(sealed<Sample>(UINT64_MAX));
  EXPECT_EQ(echo.wait(), 0);
}

TEST(TopicProcess, SegmentWhoseUsersAllDiedIsReusedEvenForAnotherType) {
  PrivateNamespace ns;
  Child first("open_and_exit", {"reused"});
  ASSERT_EQ(first.wait(), 0);
  {
    horus::Topic<Sample> same("reused");
    auto latest = same.read_latest();
    ASSERT_TRUE(latest.has_value()) << "a restarted user continues the topic";
    EXPECT_EQ(latest->seq, 7u);
  }
  horus::Topic<Other> retyped("reused");
  EXPECT_TRUE(retyped.send(sealed<Other>(1)));
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].type_name, "topic_test.Other");
}

TEST(TopicProcess, PublisherKilledWhileHoldingASlotNeitherTearsNorBlocks) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("held", {.capacity = 8});
  horus::Topic<Sample> held("held.held");
  // This handle takes the publisher lease, so the child's loan is a shared claim.
  ASSERT_TRUE(data.send(sealed<Sample>(1)));
  ASSERT_TRUE(data.try_recv().has_value());
  Child holder("hold_loan", {"held"});
  ASSERT_TRUE(held.recv(10s).has_value()) << "the child never took its loan";
  EXPECT_FALSE(data.try_recv().has_value());
  holder.kill();

  // The dead writer's ticket is skipped (and counted), not waited for.
  Child restarted("send_plain", {"held", "100", "3"});
  ASSERT_EQ(restarted.wait(), 0);
  for (std::uint64_t seq = 100; seq < 103; ++seq) {
    auto msg = data.recv(10s);
    ASSERT_TRUE(msg.has_value()) << "blocked behind the dead writer";
    EXPECT_EQ(msg->seq, seq);
    EXPECT_TRUE(valid(*msg));
  }
  EXPECT_EQ(data.lost(), 1u);

  // Going round the ring twice takes the dead writer's slot back.
  Child again("send_plain", {"held", "200", "6"});
  ASSERT_EQ(again.wait(), 0);
  for (std::uint64_t seq = 200; seq < 206; ++seq) {
    auto msg = data.recv(10s);
    ASSERT_TRUE(msg.has_value());
    EXPECT_EQ(msg->seq, seq);
    EXPECT_TRUE(valid(*msg));
  }
  EXPECT_EQ(data.lost(), 1u);
  auto latest = data.read_latest();
  ASSERT_TRUE(latest.has_value());
  EXPECT_EQ(latest->seq, 205u);
}

// The lease holder's half-written ticket was never visible: its successor writes it again.
TEST(TopicProcess, LeaseHolderKilledWithALoanOutIsSucceededWithoutALoss) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("held", {.capacity = 8});
  horus::Topic<Sample> held("held.held");
  Child holder("hold_loan", {"held"});
  ASSERT_TRUE(held.recv(10s).has_value()) << "the child never took its loan";
  holder.kill();
  Child successor("send_plain", {"held", "100", "3"});
  ASSERT_EQ(successor.wait(), 0);
  for (std::uint64_t seq = 100; seq < 103; ++seq) {
    auto msg = data.try_recv();
    ASSERT_TRUE(msg.has_value());
    EXPECT_EQ(*msg, sealed<Sample>(seq));
  }
  EXPECT_FALSE(data.try_recv().has_value());
  EXPECT_EQ(data.lost(), 0u);
}

void killed_mid_stream_then_restarted(bool single_publisher) {
  PrivateNamespace ns;
  horus::Topic<Big> data("stream", {.capacity = 16, .single_publisher = single_publisher});
  for (int round = 0; round < 3; ++round) {
    const std::uint64_t first = static_cast<std::uint64_t>(round) * 1'000'000'000ULL;
    Child publisher("stream_big", {"stream", std::to_string(first)});
    std::uint64_t received = 0;
    const auto deadline = std::chrono::steady_clock::now() + 20s;
    while (received < 2000 && !past(deadline)) {
      if (auto msg = data.recv(100ms)) {
        ASSERT_TRUE(valid(*msg)) << "torn message " << msg->seq;
        received += msg->seq >= first ? 1 : 0;
      }
    }
    ASSERT_GE(received, 2000u) << "round " << round << ": the publisher stalled";
    publisher.kill();
  }
  while (auto msg = data.try_recv()) {
    ASSERT_TRUE(valid(*msg)) << "torn message " << msg->seq;
  }
}

TEST(TopicProcess, PublisherKilledMidStreamThenRestartedNeverShowsATornMessage) {
  killed_mid_stream_then_restarted(false);
}

// Each restarted publisher takes the lease over from the killed one and rewrites its
// half-written ticket.
TEST(TopicProcess, SinglePublisherKilledMidStreamIsSucceededWithoutATornMessage) {
  killed_mid_stream_then_restarted(true);
}

TEST(TopicProcess, SerializedMessagesCrossProcessesAndOversizedOnesAreCounted) {
  PrivateNamespace ns;
  horus::Topic<Blob> data("blobs", {.capacity = 64, .max_message_size = 2048});
  constexpr std::uint64_t kCount = 40;
  Child publisher("send_blobs", {"blobs", std::to_string(kCount)});
  ASSERT_EQ(publisher.wait(), 0);
  for (std::uint64_t i = 0; i < kCount; ++i) {
    auto blob = data.try_recv();
    ASSERT_TRUE(blob.has_value()) << "message " << i;
    EXPECT_EQ(blob->seq, i);
    EXPECT_EQ(blob->text, std::string(i % 50, 'a' + static_cast<char>(i % 26)));
    EXPECT_EQ(blob->data, std::vector<std::uint8_t>(i * 7 % 1500, static_cast<std::uint8_t>(i)));
    EXPECT_EQ(blob->note.has_value(), i % 3 == 0);
  }
  EXPECT_FALSE(data.try_recv().has_value());
  EXPECT_EQ(data.stats().invalid, 0u);
  EXPECT_EQ(data.lost(), 0u);
}

// A second publisher whose membarrier fails cannot order itself against a live lease holder:
// its sends fail, counted, until the holder hands over. Destroying the holder's handle hands
// over too, so the second publisher is not stuck behind an idle holder's open-then-closed handle.
TEST(TopicProcess, ASecondPublisherWithoutMembarrierSendsOnceTheHolderLetsGo) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("fenceless");
  std::optional<horus::Topic<Sample>> holder(std::in_place, "fenceless");
  ASSERT_TRUE(holder->send(sealed<Sample>(1)));
  horus::Topic<Sample> refused("fenceless.refused");
  static_cast<void>(refused.try_recv());
  Child second("send_without_membarrier", {"fenceless"});
  if (kHolderReliesOnMembarrier) {
    ASSERT_TRUE(refused.recv(kDeadline).has_value()) << "the second publisher was never refused";
  }
  holder.reset();
  ASSERT_EQ(second.wait(), 0) << "the second publisher stayed stuck after the holder let go";
  EXPECT_EQ(sub.try_recv()->seq, 1U);
  const std::optional<Sample> handed_over = sub.try_recv();
  ASSERT_TRUE(handed_over.has_value());
  EXPECT_EQ(handed_over->seq, 99U);
  EXPECT_TRUE(valid(*handed_over));
}

// A holder killed while the second publisher waits needs no barrier: it claims nothing more.
TEST(TopicProcess, ASecondPublisherWithoutMembarrierSendsOnceTheHolderDied) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("fenceless");
  horus::Topic<Sample> held("fenceless.held");
  static_cast<void>(held.try_recv());  // subscribed before the holder says it holds
  Child holder("send_and_hold", {"fenceless", "1"});
  ASSERT_TRUE(held.recv(kDeadline).has_value()) << "the holder never sent";
  horus::Topic<Sample> refused("fenceless.refused");
  static_cast<void>(refused.try_recv());
  Child second("send_without_membarrier", {"fenceless"});
  if (kHolderReliesOnMembarrier) {
    ASSERT_TRUE(refused.recv(kDeadline).has_value()) << "the second publisher was never refused";
  }
  holder.kill();
  ASSERT_EQ(second.wait(), 0) << "the second publisher stayed stuck behind a dead holder";
  EXPECT_EQ(sub.try_recv()->seq, 0U);
  EXPECT_EQ(sub.try_recv()->seq, 99U);
}

/// The typed segment of a Sample topic, mapped a second time to play a writer the test invents.
horus::detail::ShmSegment sample_segment(const std::string& topic) {
  return horus::detail::ShmSegment::open_topic(
      topic,
      horus::detail::TypeDescriptor{
          horus::TypeInfo<Sample>::name, horus::TypeInfo<Sample>::fingerprint,
          horus::TypeInfo<Sample>::schema, true, sizeof(Sample), alignof(Sample)},
      horus::detail::SegmentOptions{8, 0, 0600, {}});
}

// Lease words name their holder by pid alone. A holder that died and whose pid the kernel gave to
// an unrelated process looks alive: the next publisher then shares the ring instead of taking
// the lease. That costs the fast path, never a message.
TEST(TopicProcess, ALeaseWhosePidWasReusedCostsTheFastPathNotAMessage) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("reused", {.capacity = 8});
  Child unrelated("sleep_in_recv", {"elsewhere"});
  {
    const horus::detail::ShmSegment segment = sample_segment("reused");
    segment.ring().control->publisher_lease.store(static_cast<std::uint64_t>(unrelated.pid())
                                                  << 32);
  }
  horus::Topic<Sample> pub("reused");
  for (std::uint64_t seq = 0; seq < 20; ++seq) {
    ASSERT_TRUE(pub.send(sealed<Sample>(seq))) << seq;
    const std::optional<Sample> got = sub.try_recv();
    ASSERT_TRUE(got.has_value()) << seq;
    EXPECT_EQ(got->seq, seq);
    EXPECT_TRUE(valid(*got));
  }
  EXPECT_EQ(pub.stats().send_failures, 0U);
  EXPECT_EQ(sub.lost(), 0U);
}

// Slot claims name their writer by pid alone too. A writer that died mid-message and whose pid was
// reused keeps its slot for as long as the unrelated process lives: the next lap's send there is
// refused (counted) and a reader skips the ticket after its stall limit (counted in lost()); the
// slot is taken back once that process is gone. Never a torn message.
TEST(TopicProcess, ASlotClaimWhosePidWasReusedCostsASendPerLapNotATornMessage) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("reused", {.capacity = 8});
  horus::Topic<Sample> first("reused");
  horus::Topic<Sample> second("reused");
  ASSERT_TRUE(first.send(sealed<Sample>(0)));
  ASSERT_TRUE(second.send(sealed<Sample>(1)));  // shares the ring
  EXPECT_EQ(sub.try_recv()->seq, 0U);
  EXPECT_EQ(sub.try_recv()->seq, 1U);
  Child unrelated("sleep_in_recv", {"elsewhere"});
  const horus::detail::ShmSegment segment = sample_segment("reused");
  const horus::detail::RingView& ring = segment.ring();
  // The dead writer took ticket 2, claimed its slot and died mid-copy; its pid is reused.
  const std::uint64_t ticket = 2;
  ring.control->write_index.fetch_add(1);
  ring.slot_claim(ticket).owner.store(static_cast<std::uint32_t>(unrelated.pid()));
  ring.slot_claim(ticket).claim.store(2 * ticket + 1);
  ring.slot(ticket).seq.store(2 * ticket + 1);

  for (std::uint64_t seq = 3; seq < 10; ++seq) {
    ASSERT_TRUE(second.send(sealed<Sample>(seq))) << seq;
  }
  EXPECT_FALSE(second.send(sealed<Sample>(10))) << "wrote over the slot of a live-looking writer";
  EXPECT_EQ(second.stats().send_failures, 1U);
  for (std::uint64_t seq = 3; seq < 10; ++seq) {
    const std::optional<Sample> got = sub.recv(kDeadline);
    ASSERT_TRUE(got.has_value()) << seq;
    EXPECT_EQ(got->seq, seq);
    EXPECT_TRUE(valid(*got));
  }
  EXPECT_EQ(sub.lost(), 1U) << "the stalled ticket";

  unrelated.kill();
  // Ticket 18 lands in the slot again, a lap after the refused ticket 10.
  for (std::uint64_t seq = 11; seq < 19; ++seq) {
    EXPECT_TRUE(second.send(sealed<Sample>(seq))) << "the slot stayed held by a dead pid";
  }
  for (std::uint64_t seq = 11; seq < 19; ++seq) {
    const std::optional<Sample> got = sub.recv(kDeadline);
    ASSERT_TRUE(got.has_value()) << seq;
    EXPECT_EQ(got->seq, seq);
  }
  EXPECT_EQ(sub.lost(), 2U) << "the stalled ticket and the refused one";
}

TEST(TopicProcess, GenericMessagesCrossProcesses) {
  PrivateNamespace ns;
  horus::Topic<horus::msg::GenericMessage> data("custom_data");
  constexpr std::uint64_t kCount = 30;
  Child publisher("send_generic", {"custom_data", std::to_string(kCount)});
  ASSERT_EQ(publisher.wait(), 0);
  for (std::uint64_t i = 0; i < kCount; ++i) {
    const std::optional<horus::msg::GenericMessage> msg = data.try_recv();
    ASSERT_TRUE(msg.has_value()) << "message " << i;
    EXPECT_EQ(msg->to_value<Reading>(), reading(i));
    EXPECT_EQ(msg->metadata, i % 2 == 1 ? std::optional<std::string>("battery " + std::to_string(i))
                                        : std::nullopt);
  }
  EXPECT_FALSE(data.try_recv().has_value());
  EXPECT_EQ(data.stats().invalid, 0u);
  const std::vector<horus::TopicInfo> topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].type_name, "horus.msg.GenericMessage");
  EXPECT_EQ(topics[0].message_count, kCount);
}

TEST(TopicProcess, PlainValuesCrossProcesses) {
  PrivateNamespace ns;
  horus::Topic<std::uint64_t> counters("odometer");
  horus::Topic<std::array<float, 3>> triples("odometer.xyz");
  constexpr std::uint64_t kCount = 50;
  Child publisher("send_values", {"odometer", std::to_string(kCount)});
  ASSERT_EQ(publisher.wait(), 0);
  for (std::uint64_t i = 0; i < kCount; ++i) {
    EXPECT_EQ(counters.try_recv(), i * 0x0101010101010101ULL) << i;
    const auto x = static_cast<float>(i);
    EXPECT_EQ(triples.try_recv(), (std::array<float, 3>{x, x / 2, -x})) << i;
  }
  EXPECT_FALSE(counters.try_recv().has_value());
  EXPECT_FALSE(triples.try_recv().has_value());
}

void blocking_recv_wakes(Sender who) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("wake", {.single_publisher = who == Sender::single});
  if (who == Sender::second) {
    ASSERT_TRUE(data.send(sealed<Sample>(1)));
    ASSERT_TRUE(data.try_recv().has_value());
  }
  Child sender("send_after", {"wake", "50"});
  auto msg = data.recv(20s);
  ASSERT_TRUE(msg.has_value());
  EXPECT_EQ(msg->seq, 5u);
  EXPECT_EQ(sender.wait(), 0);
  EXPECT_FALSE(data.recv(50ms).has_value()) << "nothing else was sent";
}

TEST(TopicProcess, BlockingRecvWakesOnASendFromAnotherProcess) {
  blocking_recv_wakes(Sender::first);
}

TEST(TopicProcess, BlockingRecvWakesOnASecondPublishersSendFromAnotherProcess) {
  blocking_recv_wakes(Sender::second);
}

TEST(TopicProcess, BlockingRecvWakesOnASinglePublishersSendFromAnotherProcess) {
  blocking_recv_wakes(Sender::single);
}

TEST(TopicProcess, NotifierWaitsForATopicThatDoesNotExistYet) {
  PrivateNamespace ns;
  horus::detail::TopicNotifier notifier("future");
  EXPECT_FALSE(notifier.wait(20ms));
  Child sender("send_after", {"future", "20"});
  EXPECT_TRUE(notifier.wait(20s));
  EXPECT_EQ(sender.wait(), 0);
  EXPECT_FALSE(notifier.wait(20ms)) << "one message wakes one wait";
}

void wait_set_wakes(Sender who) {
  PrivateNamespace ns;
  horus::Topic<Sample> create("loud", {.single_publisher = who == Sender::single});
  if (who == Sender::second) {
    ASSERT_TRUE(create.send(sealed<Sample>(1)));
  }
  horus::detail::TopicWaitSet set({"quiet", "loud"});
  Child sender("send_after", {"loud", "20"});
  EXPECT_EQ(set.wait(20s), std::optional<std::size_t>(1));
  EXPECT_EQ(sender.wait(), 0);
  EXPECT_FALSE(set.wait(20ms).has_value());
}

TEST(TopicProcess, WaitSetWakesOnASendFromAnotherProcess) { wait_set_wakes(Sender::first); }

TEST(TopicProcess, WaitSetWakesOnASecondPublishersSendFromAnotherProcess) {
  wait_set_wakes(Sender::second);
}

TEST(TopicProcess, WaitSetWakesOnASinglePublishersSendFromAnotherProcess) {
  wait_set_wakes(Sender::single);
}

TEST(TopicProcess, FullShmIsAClearErrorNotSigbus) {
  PrivateNamespace ns;
  Child child("no_room", {"roomless"});
  EXPECT_EQ(child.wait(), 0);
}

TEST(TopicProcess, IntrospectionListsTypesUsersAndTraffic) {
  PrivateNamespace ns;
  horus::Topic<Sample> listener("listed", {.capacity = 32});
  EXPECT_FALSE(listener.try_recv().has_value());
  // The stamp's own clock: time() reads the second the kernel last ticked into, which lags
  // system_clock (whose floor could already be the next second) by up to a tick.
  const auto before = std::chrono::system_clock::from_time_t(std::time(nullptr));
  Child publisher("send_plain", {"listed", "0", "5"});
  ASSERT_EQ(publisher.wait(), 0);
  const auto after = std::chrono::system_clock::now();
  horus::detail::TopicNotifier notifier("untyped");

  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 2u);
  const horus::TopicInfo& listed = topics[0];
  EXPECT_EQ(listed.name, "listed");
  EXPECT_EQ(listed.error, "");
  EXPECT_EQ(listed.type_name, "topic_test.Sample");
  EXPECT_EQ(listed.fingerprint, horus::TypeInfo<Sample>::fingerprint);
  EXPECT_EQ(listed.schema, horus::TypeInfo<Sample>::schema);
  EXPECT_TRUE(listed.is_pod);
  EXPECT_EQ(listed.capacity, 32u);
  EXPECT_EQ(listed.max_message_size, sizeof(Sample));
  EXPECT_EQ(listed.publishers, 0u) << "the publisher exited";
  EXPECT_EQ(listed.subscribers, 1u);
  EXPECT_EQ(listed.message_count, 5u);
  ASSERT_TRUE(listed.last_send.has_value());
  EXPECT_GE(*listed.last_send, before);
  EXPECT_LE(*listed.last_send, after);
  EXPECT_EQ(listed.last_send->time_since_epoch() % 1s, std::chrono::system_clock::duration::zero())
      << "stamped to the whole second";
  EXPECT_EQ(topics[1].name, "untyped");
  EXPECT_EQ(topics[1].type_name, "");
  EXPECT_EQ(topics[1].error, "");
}

TEST(TopicProcess, SegmentsAreOwnerOnlyInAPerNamespaceFolder) {
  PrivateNamespace ns;
  horus::Topic<Sample> data("private");
  struct stat info {};
  const std::string directory = horus::detail::namespace_directory(ns.name());
  ASSERT_EQ(::stat(directory.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 07777, 0700u);
  ASSERT_EQ(::stat((directory + "/private").c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 07777, 0600u);
}

}  // namespace
