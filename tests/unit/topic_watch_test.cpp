// horus::bridge::TopicWatch and the RawTopic wait it rests on (begin_wait/end_wait): a message sent
// by another thread or process makes the watch's descriptor readable, no wake-up is lost when a
// send races the arming, and a watch that ends while armed leaves no sleeper announced.
#include <gtest/gtest.h>
#include <linux/audit.h>
#include <linux/filter.h>
#include <linux/seccomp.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include <horus/bridge/topic_watch.hpp>
#include <horus/detail/shm_segment.hpp>
#include <horus/error.hpp>
#include <horus/raw_topic.hpp>
#include <horus/topic.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using horus::bridge::TopicWatch;
using topic_test::PrivateNamespace;
using topic_test::Sample;
using topic_test::sealed;

horus::RawTopic open_raw(const std::string& name) {
  return horus::RawTopic(name, horus::type_identity<Sample>(), horus::TopicOptions{});
}

bool send(horus::RawTopic& topic, std::uint64_t seq) {
  const Sample message = sealed<Sample>(seq);
  return topic.send(std::as_bytes(std::span(&message, 1)));
}

/// The message the last receive left in `topic`'s buffer.
Sample received(horus::RawTopic& topic) {
  Sample message{};
  std::memcpy(&message, topic.received(sizeof message).data(), sizeof message);
  return message;
}

/// Whether `fd` turns readable within `timeout`.
bool readable_within(int fd, std::chrono::milliseconds timeout) {
  pollfd entry{fd, POLLIN, 0};
  return ::poll(&entry, 1, static_cast<int>(timeout.count())) == 1 && (entry.revents & POLLIN);
}

/// Sleepers announced on a topic (the high bits of its write index), read through a
/// control-page handle of the test's own.
std::uint64_t announced_sleepers(const std::string& topic) {
  const horus::detail::ShmSegment control =
      horus::detail::ShmSegment::open_control(topic, {0, 0, 0600, {}, false});
  return control.control().ring.write_index.load() >> 56;
}

/// Makes io_uring_setup(2) fail with EPERM in this process, as a sandbox does.
bool forbid_io_uring() {
  sock_filter filter[] = {
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, arch)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, AUDIT_ARCH_X86_64, 1, 0),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
      BPF_STMT(BPF_LD | BPF_W | BPF_ABS, offsetof(seccomp_data, nr)),
      BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, SYS_io_uring_setup, 0, 1),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ERRNO | EPERM),
      BPF_STMT(BPF_RET | BPF_K, SECCOMP_RET_ALLOW),
  };
  sock_fprog program{static_cast<unsigned short>(std::size(filter)), filter};
  return ::prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) == 0 &&
         ::prctl(PR_SET_SECCOMP, SECCOMP_MODE_FILTER, &program) == 0;
}

/// watch_without_io_uring: with io_uring forbidden, 0 when supported() says no and a watch is
/// refused with a horus::Error that names the topic and the way out.
int role_watch_without_io_uring(const std::vector<std::string>&) {
  if (!forbid_io_uring()) {
    return 10;
  }
  if (TopicWatch::supported()) {
    return 11;
  }
  horus::RawTopic topic = open_raw("refused");
  try {
    TopicWatch watch(topic);
  } catch (const horus::Error& error) {
    const std::string text = error.what();
    const bool says_why = text.find("'refused'") != std::string::npos &&
                          text.find("RawTopic::recv") != std::string::npos;
    return says_why ? 0 : 12;
  }
  return 13;
}

const bool kRolesRegistered = [] {
  topic_test::roles()["watch_without_io_uring"] = role_watch_without_io_uring;
  return true;
}();
// Runs before main: a re-executed child plays its role and exits here.
const int kRoleStatus = topic_test::dispatch_role();

TEST(TopicWatchSupport, IsRefusedWithAReasonWhereIoUringIsForbidden) {
  PrivateNamespace ns;
  topic_test::Child child("watch_without_io_uring", {});
  EXPECT_EQ(child.wait(), 0) << "10: no seccomp filter, 11: supported() said yes, 12: the "
                                "error did not name the topic and the fallback, 13: no error";
}

TEST(RawTopicWait, BeginWaitIsEmptyWhileAMessageWaitsToBeRead) {
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("waited");
  horus::RawTopic publisher = open_raw("waited");
  ASSERT_TRUE(send(publisher, 1));
  EXPECT_FALSE(topic.begin_wait().has_value()) << "a message was there to read";
  EXPECT_EQ(announced_sleepers("waited"), 0U) << "an empty begin_wait leaves nothing announced";
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_TRUE(topic.begin_wait().has_value()) << "nothing left to read";
  topic.end_wait();
}

TEST(RawTopicWait, ASendAfterBeginWaitChangesTheWordAndEndWaitWithdrawsTheAnnouncement) {
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("waited");
  horus::RawTopic publisher = open_raw("waited");
  const std::optional<horus::TopicWaitWord> wait = topic.begin_wait();
  ASSERT_TRUE(wait.has_value());
  EXPECT_EQ(wait->word->load(), wait->expected) << "nothing was sent yet";
  EXPECT_EQ(announced_sleepers("waited"), 1U);
  ASSERT_TRUE(send(publisher, 1));
  EXPECT_NE(wait->word->load(), wait->expected)
      << "a send seeing the announced sleeper bumps the word, so a futex wait on it ends";
  topic.end_wait();
  EXPECT_EQ(announced_sleepers("waited"), 0U);
  topic.end_wait();
  EXPECT_EQ(announced_sleepers("waited"), 0U) << "a second end_wait withdraws nothing more";
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_EQ(received(topic), sealed<Sample>(1));
}

TEST(RawTopicWait, ATopicDestroyedWhileWaitingWithdrawsItsAnnouncement) {
  PrivateNamespace ns;
  {
    horus::RawTopic topic = open_raw("waited");
    ASSERT_TRUE(topic.begin_wait().has_value());
    ASSERT_TRUE(topic.begin_wait().has_value()) << "a second begin_wait ends the first";
    EXPECT_EQ(announced_sleepers("waited"), 1U);
  }
  EXPECT_EQ(announced_sleepers("waited"), 0U);
}

/// Two publishers share `name`'s ring (the second took it over from the lease); `reader` has read
/// their two messages.
void share_the_ring(horus::RawTopic& reader, horus::RawTopic& first, horus::RawTopic& second) {
  ASSERT_TRUE(send(first, 1));
  ASSERT_TRUE(send(second, 2));
  ASSERT_GE(reader.try_recv(), 0);
  ASSERT_GE(reader.try_recv(), 0);
  ASSERT_LT(reader.try_recv(), 0);
}

TEST(RawTopicWait, BehindATicketTakenBeforeTheAnnouncementTheWaitIsInSlices) {
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("waited");
  horus::RawTopic first = open_raw("waited");
  horus::RawTopic second = open_raw("waited");
  share_the_ring(topic, first, second);
  std::optional<horus::TopicWaitWord> wait = topic.begin_wait();
  ASSERT_TRUE(wait.has_value());
  EXPECT_EQ(wait->recheck_after, std::chrono::nanoseconds::zero())
      << "every later ticket's publisher wakes the word";
  topic.end_wait();

  // A loan takes its ticket now: its publisher saw no sleeper, so its commit wakes nobody.
  ASSERT_NE(second.loan(), nullptr);
  wait = topic.begin_wait();
  ASSERT_TRUE(wait.has_value());
  EXPECT_GT(wait->recheck_after, std::chrono::nanoseconds::zero())
      << "the loan's commit will not wake this waiter, so it must look again by itself";
  topic.end_wait();
  second.release_loan();
}

/// Where the kernel has no io_uring futex waits (Debian 12's Linux 6.1), each case checks what
/// the bridges then rely on instead: a watch is refused naming why, and they choose their
/// reader threads (whose paths pytest_remote_threaded and pytest_view_threaded test).
class TopicWatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (TopicWatch::supported()) return;
    refused_ = true;
    EXPECT_EQ(horus::bridge::choose_topic_wait("HORUS_TOPIC_WATCH_TEST_UNSET"),
              horus::bridge::TopicWait::ReaderThread);
    PrivateNamespace ns;
    horus::RawTopic topic = open_raw("refused");
    try {
      TopicWatch watch(topic);
      ADD_FAILURE() << "a watch was made where io_uring futex waits are not supported";
    } catch (const horus::Error& error) {
      EXPECT_NE(std::string(error.what()).find("io_uring"), std::string::npos) << error.what();
    }
  }

  /// The kernel refused io_uring futex waits: SetUp checked the fallback, the case has no more.
  bool refused_ = false;
};

TEST_F(TopicWatchTest, ArmIsFalseWhenAMessageIsAlreadyThere) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  horus::RawTopic publisher = open_raw("watched");
  TopicWatch watch(topic);
  ASSERT_TRUE(send(publisher, 1));
  EXPECT_FALSE(watch.arm()) << "the message is there to read now";
  EXPECT_FALSE(watch.armed());
  EXPECT_FALSE(readable_within(watch.fd(), 0ms));
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_TRUE(watch.arm()) << "nothing left to read";
  EXPECT_TRUE(watch.armed());
  watch.complete();
}

TEST_F(TopicWatchTest, AMessageFromAnotherThreadMakesTheDescriptorReadable) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  TopicWatch watch(topic);
  ASSERT_TRUE(watch.arm());
  EXPECT_FALSE(readable_within(watch.fd(), 20ms)) << "nothing was sent";

  std::thread publisher([] {
    horus::RawTopic handle = open_raw("watched");
    std::this_thread::sleep_for(20ms);
    send(handle, 7);
  });
  const bool woken = readable_within(watch.fd(), 10'000ms);
  publisher.join();
  ASSERT_TRUE(woken) << "the send did not make the ring's descriptor readable";
  watch.complete();
  EXPECT_FALSE(watch.armed());
  EXPECT_FALSE(readable_within(watch.fd(), 0ms)) << "complete() took every completion";
  EXPECT_EQ(announced_sleepers("watched"), 0U) << "complete() withdrew the announcement";
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_EQ(received(topic), sealed<Sample>(7));
}

TEST_F(TopicWatchTest, AMessageFromAnotherProcessMakesTheDescriptorReadable) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  TopicWatch watch(topic);
  ASSERT_TRUE(watch.arm());

  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    int status = 1;
    try {
      horus::Topic<Sample> publisher("watched");
      std::this_thread::sleep_for(20ms);
      status = publisher.send(sealed<Sample>(9)) ? 0 : 2;
    } catch (...) {
      status = 3;
    }
    ::_exit(status);
  }
  const bool woken = readable_within(watch.fd(), 10'000ms);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "the child could not publish";
  ASSERT_TRUE(woken) << "the other process's send did not make the descriptor readable";
  watch.complete();
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_EQ(received(topic), sealed<Sample>(9));
}

/// `rounds` messages, each sent soon after the previous one was read, so that sends fall at every
/// point of the watcher's complete / read / arm / poll; `publishers` handles take turns (two
/// share the ring, one keeps the fast lease). Every message must be read, each after a wake-up
/// or an arm() that found it.
void expect_no_lost_wake_up(int rounds, int publishers) {
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("rounds");
  TopicWatch watch(topic);
  std::atomic<int> read_count{0};
  std::atomic<bool> stop{false};
  std::thread publisher([&] {
    std::vector<std::unique_ptr<horus::RawTopic>> handles;
    for (int i = 0; i < publishers; ++i) {
      handles.push_back(std::make_unique<horus::RawTopic>("rounds", horus::type_identity<Sample>(),
                                                          horus::TopicOptions{}));
    }
    for (int sent = 0; sent < rounds && !stop.load();) {
      if (read_count.load(std::memory_order_acquire) == sent) {
        // A varying pause, so that sends land all over the watcher's arming.
        for (int pause = (sent * 37) % 2000; pause > 0; --pause) {
          std::atomic_signal_fence(std::memory_order_seq_cst);
        }
        send(*handles[static_cast<std::size_t>(sent % publishers)],
             static_cast<std::uint64_t>(sent));
        ++sent;
      }
    }
  });
  int lost_at = -1;
  int read = 0;
  int slept = 0;
  while (read < rounds) {
    watch.complete();
    while (topic.try_recv() >= 0) {
      EXPECT_EQ(received(topic).seq, static_cast<std::uint64_t>(read));
      read_count.store(++read, std::memory_order_release);
    }
    if (read == rounds) {
      break;
    }
    if (!watch.arm()) {
      continue;
    }
    ++slept;
    if (!readable_within(watch.fd(), 5'000ms)) {
      lost_at = read;
      break;
    }
  }
  stop.store(true);
  publisher.join();
  watch.complete();
  EXPECT_EQ(lost_at, -1) << "no wake-up within 5 s for message " << lost_at << " of " << rounds;
  EXPECT_EQ(read, rounds);
  EXPECT_EQ(announced_sleepers("rounds"), 0U);
  EXPECT_GT(slept, 0) << "no round went through a wait";
}

TEST_F(TopicWatchTest, NoWakeUpIsLostOverTenThousandRoundsWithOnePublisher) {
  if (refused_) return;
  expect_no_lost_wake_up(10'000, 1);
}

TEST_F(TopicWatchTest, NoWakeUpIsLostOverTenThousandRoundsWithPublishersSharingTheRing) {
  if (refused_) return;
  expect_no_lost_wake_up(10'000, 2);
}

TEST_F(TopicWatchTest, BehindATicketInFlightItLooksAgainWithoutAWakeUp) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  horus::RawTopic first = open_raw("watched");
  horus::RawTopic second = open_raw("watched");
  share_the_ring(topic, first, second);
  std::byte* payload = second.loan();
  ASSERT_NE(payload, nullptr);
  TopicWatch watch(topic);
  ASSERT_TRUE(watch.arm());
  const Sample message = sealed<Sample>(3);
  std::memcpy(payload, &message, sizeof message);
  ASSERT_TRUE(second.publish());  // wakes nobody: the ticket was taken before the announcement

  const auto deadline = std::chrono::steady_clock::now() + 2s;
  std::ptrdiff_t size = -1;
  while (size < 0 && std::chrono::steady_clock::now() < deadline) {
    if (watch.armed() && !readable_within(watch.fd(), 2'000ms)) {
      break;
    }
    watch.complete();
    size = topic.try_recv();
    if (size < 0) {
      watch.arm();
    }
  }
  ASSERT_EQ(size, static_cast<std::ptrdiff_t>(sizeof(Sample)))
      << "the wait's timeout did not bring the watch back to the committed message";
  EXPECT_EQ(received(topic), message);
}

TEST_F(TopicWatchTest, CompleteBeforeAnyWakeUpCancelsTheWait) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  horus::RawTopic publisher = open_raw("watched");
  TopicWatch watch(topic);
  ASSERT_TRUE(watch.arm());
  EXPECT_EQ(announced_sleepers("watched"), 1U);
  watch.complete();  // as after a spurious wake-up of the loop
  EXPECT_FALSE(watch.armed());
  EXPECT_EQ(announced_sleepers("watched"), 0U);
  EXPECT_FALSE(readable_within(watch.fd(), 0ms)) << "the cancelled wait left a completion";
  ASSERT_TRUE(send(publisher, 1));
  EXPECT_FALSE(readable_within(watch.fd(), 20ms)) << "the cancelled wait was still woken";
  EXPECT_FALSE(watch.arm()) << "the message sent meanwhile is there to read";
}

TEST_F(TopicWatchTest, DestroyedWhileArmedItLeavesNothingAnnouncedNorWaiting) {
  if (refused_) return;
  PrivateNamespace ns;
  horus::RawTopic topic = open_raw("watched");
  horus::RawTopic publisher = open_raw("watched");
  {
    TopicWatch watch(topic);
    ASSERT_TRUE(watch.arm());
    EXPECT_EQ(announced_sleepers("watched"), 1U);
  }
  EXPECT_EQ(announced_sleepers("watched"), 0U);
  ASSERT_TRUE(send(publisher, 1));
  TopicWatch again(topic);
  EXPECT_FALSE(again.arm()) << "the message is there to read";
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  ASSERT_TRUE(again.arm());
  ASSERT_TRUE(send(publisher, 2));
  ASSERT_TRUE(readable_within(again.fd(), 10'000ms)) << "a new watch on the same topic is woken";
  again.complete();
  ASSERT_EQ(topic.try_recv(), static_cast<std::ptrdiff_t>(sizeof(Sample)));
  EXPECT_EQ(received(topic), sealed<Sample>(2));
}

}  // namespace
