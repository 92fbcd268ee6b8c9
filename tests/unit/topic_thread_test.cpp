// Topics between threads of one process: the API contract, loans, blocking and the notifier.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>
#include <thread>
#include <vector>

#include <horus/detail/shm_segment.hpp>
#include <horus/internal/topic_notifier.hpp>
#include <horus/internal/topic_wait_set.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_test/blob.hpp>
#include <topic_test/other.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using topic_test::Blob;
using topic_test::Other;
using topic_test::PrivateNamespace;
using topic_test::Sample;
using topic_test::sealed;
using topic_test::valid;

TEST(TopicThread, OneHandleSendsAndAnotherReceivesInOrder) {
  PrivateNamespace ns;
  horus::Topic<Sample> pub("chatter");
  horus::Topic<Sample> sub("chatter");
  EXPECT_FALSE(sub.has_msg());
  for (std::uint64_t i = 0; i < 10; ++i) {
    ASSERT_TRUE(pub.send(sealed<Sample>(i)));
  }
  EXPECT_TRUE(sub.has_msg());
  for (std::uint64_t i = 0; i < 10; ++i) {
    auto msg = sub.try_recv();
    ASSERT_TRUE(msg.has_value());
    EXPECT_EQ(*msg, sealed<Sample>(i));
  }
  EXPECT_FALSE(sub.try_recv().has_value());
  auto own = pub.try_recv();
  ASSERT_TRUE(own.has_value()) << "a handle also receives what it sent";
  EXPECT_EQ(own->seq, 0u);
}

TEST(TopicThread, LoanWritesInPlaceAndAnUnpublishedLoanSendsNothing) {
  PrivateNamespace ns;
  horus::Topic<Sample> pub("loaned");
  horus::Topic<Sample> sub("loaned");
  {
    auto dropped = pub.loan();
    dropped->seq = 99;
  }
  auto loan = pub.loan();
  topic_test::seal(*loan, 5);
  ASSERT_TRUE(pub.publish(std::move(loan)));
  auto msg = sub.try_recv();
  ASSERT_TRUE(msg.has_value());
  EXPECT_EQ(*msg, sealed<Sample>(5));
  EXPECT_FALSE(sub.try_recv().has_value());
  EXPECT_EQ(sub.lost(), 0u);
  EXPECT_EQ(sub.read_latest()->seq, 5u);
}

TEST(TopicThread, CapacityIsRoundedToAPowerOfTwoAndAdoptedByLaterOpeners) {
  PrivateNamespace ns;
  horus::Topic<Sample> first("sized", {.capacity = 100});
  horus::Topic<Sample> second("sized", {.capacity = 4});
  EXPECT_EQ(first.capacity(), 128u);
  EXPECT_EQ(second.capacity(), 128u);
}

TEST(TopicThread, AnotherTypeInTheSameProcessIsRefused) {
  PrivateNamespace ns;
  horus::Topic<Sample> incumbent("typed");
  EXPECT_THROW(horus::Topic<Other>("typed"), horus::Error);
  EXPECT_THROW(horus::Topic<Blob>("typed"), horus::Error);
  horus::Topic<Sample> sub("typed");
  EXPECT_TRUE(incumbent.send(sealed<Sample>(1)));
  EXPECT_TRUE(sub.try_recv().has_value());
}

TEST(TopicThread, InvalidNamesAreRejected) {
  PrivateNamespace ns;
  EXPECT_THROW(horus::Topic<Sample>("a/b"), horus::Error);
  EXPECT_THROW(horus::Topic<Sample>(".."), horus::Error);
  EXPECT_THROW(horus::Topic<Sample>(""), horus::Error);
  EXPECT_THROW(horus::Topic<Sample>("x", {.capacity = 0}), horus::Error);
}

TEST(TopicThread, ConcurrentPublishersAndSubscribersSeeEveryMessageInOrder) {
  PrivateNamespace ns;
  constexpr std::size_t kPublishers = 3;
  constexpr std::uint64_t kEach = 5000;
  // Large enough that nobody is lapped: every subscriber must see everything.
  horus::Topic<Sample> create("busy", {.capacity = 16384});
  std::vector<horus::Topic<Sample>> subs;
  for (int s = 0; s < 2; ++s) {
    subs.emplace_back("busy");
  }
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (auto& sub : subs) {
    threads.emplace_back([&sub, &failures] {
      std::vector<std::uint64_t> next(kPublishers, 0);
      for (std::uint64_t got = 0; got < kPublishers * kEach;) {
        auto msg = sub.recv(10s);
        if (!msg) {
          ++failures;
          return;
        }
        std::size_t from = kPublishers;
        for (std::size_t p = 0; p < kPublishers; ++p) {
          if (msg->seq == next[p] && *msg == sealed<Sample>(msg->seq, p)) {
            from = p;
          }
        }
        if (from == kPublishers) {
          ++failures;
          return;
        }
        ++next[from];
        ++got;
      }
    });
  }
  for (std::size_t p = 0; p < kPublishers; ++p) {
    threads.emplace_back([p, &failures] {
      horus::Topic<Sample> pub("busy");
      for (std::uint64_t i = 0; i < kEach; ++i) {
        if (!pub.send(sealed<Sample>(i, p))) {
          ++failures;
        }
      }
    });
  }
  for (auto& thread : threads) {
    thread.join();
  }
  EXPECT_EQ(failures.load(), 0);
  for (auto& sub : subs) {
    EXPECT_EQ(sub.lost(), 0u);
  }
}

TEST(TopicThread, RecvWakesOnSendAndTimesOutWhenNothingComes) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("wake");
  EXPECT_FALSE(sub.recv(20ms).has_value());
  std::thread sender([] {
    horus::Topic<Sample> pub("wake");
    std::this_thread::sleep_for(20ms);
    pub.send(sealed<Sample>(3));
  });
  auto msg = sub.recv(20s);
  sender.join();
  ASSERT_TRUE(msg.has_value());
  EXPECT_EQ(msg->seq, 3u);
}

TEST(TopicThread, NotifierWakesOnAnyTypeAndOnInterrupt) {
  PrivateNamespace ns;
  horus::detail::TopicNotifier notifier("events");
  std::thread sender([] {
    horus::Topic<Blob> pub("events");
    std::this_thread::sleep_for(20ms);
    Blob blob;
    blob.text = "hello";
    pub.send(blob);
  });
  EXPECT_TRUE(notifier.wait(20s));
  sender.join();

  std::thread stopper([&notifier] {
    std::this_thread::sleep_for(20ms);
    notifier.interrupt();
  });
  EXPECT_FALSE(notifier.wait(20s)) << "interrupt() ends the wait without a message";
  stopper.join();

  horus::Topic<Blob> pub("events");
  pub.send(Blob{});
  EXPECT_TRUE(notifier.wait(0ns)) << "a message sent between two waits is not missed";
}

TEST(TopicThread, WaitSetWakesOnWhicheverTopicReceives) {
  PrivateNamespace ns;
  horus::detail::TopicWaitSet set({"left", "right", "later"});
  EXPECT_EQ(set.size(), 3u);
  EXPECT_FALSE(set.wait(10ms).has_value());
  std::thread sender([] {
    horus::Topic<Sample> right("right");
    std::this_thread::sleep_for(20ms);
    right.send(sealed<Sample>(1));
  });
  EXPECT_EQ(set.wait(20s), std::optional<std::size_t>(1));
  sender.join();

  horus::Topic<Sample> left("left");
  horus::Topic<Blob> later("later");
  left.send(sealed<Sample>(2));
  later.send(Blob{});
  EXPECT_EQ(set.wait(0ns), std::optional<std::size_t>(0));
  EXPECT_EQ(set.wait(0ns), std::optional<std::size_t>(2)) << "the other arrival is remembered";
  EXPECT_FALSE(set.wait(10ms).has_value());

  std::thread stopper([&set] {
    std::this_thread::sleep_for(20ms);
    set.interrupt();
  });
  EXPECT_FALSE(set.wait(20s).has_value());
  stopper.join();
  EXPECT_THROW(horus::detail::TopicWaitSet({}), horus::Error);
}

TEST(TopicThread, SerializedOverMaximumSizeIsRefusedAndCounted) {
  PrivateNamespace ns;
  horus::Topic<Blob> pub("blob", {.capacity = 8, .max_message_size = 256});
  horus::Topic<Blob> sub("blob");
  Blob small;
  small.seq = 1;
  small.text = "fits";
  Blob large;
  large.data.assign(1000, 7);
  EXPECT_TRUE(pub.send(small));
  EXPECT_FALSE(pub.send(large));
  EXPECT_EQ(pub.stats().oversized, 1u);
  EXPECT_EQ(pub.stats().send_failures, 1u);
  small.seq = 2;
  EXPECT_TRUE(pub.send(small));
  EXPECT_EQ(sub.try_recv()->seq, 1u);
  EXPECT_EQ(sub.try_recv()->seq, 2u) << "the refused message leaves no hole";
  EXPECT_FALSE(sub.try_recv().has_value());
  EXPECT_EQ(sub.lost(), 0u);
  EXPECT_EQ(sub.read_latest()->seq, 2u);
}

TEST(TopicThread, SinglePublisherTopicLetsOneHandleSendAtATime) {
  PrivateNamespace ns;
  horus::Topic<Sample> sub("solo", {.capacity = 8, .single_publisher = true});
  std::optional<horus::Topic<Sample>> first(std::in_place, "solo");
  horus::Topic<Sample> second("solo");
  ASSERT_TRUE(first->send(sealed<Sample>(0)));
  ASSERT_TRUE(first->send(sealed<Sample>(1)));

  EXPECT_FALSE(second.send(sealed<Sample>(100)));
  {
    auto loan = second.loan();
    topic_test::seal(*loan, 101);
    EXPECT_FALSE(second.publish(std::move(loan)));
  }
  EXPECT_EQ(second.stats().not_the_publisher, 2u);
  EXPECT_EQ(second.stats().send_failures, 2u);

  // The lease goes with the handle: once it is gone, another handle may publish.
  first.reset();
  ASSERT_TRUE(second.send(sealed<Sample>(2)));
  auto loan = second.loan();
  topic_test::seal(*loan, 3);
  ASSERT_TRUE(second.publish(std::move(loan)));
  {
    auto dropped = second.loan();
    dropped->seq = 99;
  }
  ASSERT_TRUE(second.send(sealed<Sample>(4)));

  for (std::uint64_t i = 0; i < 5; ++i) {
    auto msg = sub.try_recv();
    ASSERT_TRUE(msg.has_value()) << i;
    EXPECT_EQ(*msg, sealed<Sample>(i));
  }
  EXPECT_FALSE(sub.try_recv().has_value());
  EXPECT_EQ(sub.lost(), 0u);
  EXPECT_EQ(sub.read_latest()->seq, 4u);
  EXPECT_FALSE(sub.send(sealed<Sample>(5))) << "second still holds the lease";

  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_TRUE(topics[0].single_publisher);
  EXPECT_EQ(topics[0].message_count, 6u) << "five messages and the dropped loan's ticket";
}

TEST(TopicThread, AssigningOverALeaseHolderGivesItsLeaseBack) {
  PrivateNamespace ns;
  horus::Topic<Sample> holder("solo.a", {.single_publisher = true});
  horus::Topic<Sample> other("solo.b", {.single_publisher = true});
  ASSERT_TRUE(holder.send(sealed<Sample>(1)));
  ASSERT_TRUE(other.send(sealed<Sample>(2)));
  horus::Topic<Sample> successor("solo.a");
  EXPECT_FALSE(successor.send(sealed<Sample>(3)));
  holder = std::move(other);
  EXPECT_TRUE(successor.send(sealed<Sample>(4))) << "solo.a's lease was not given back";
  EXPECT_TRUE(holder.send(sealed<Sample>(5))) << "solo.b's lease moved with the handle";
  EXPECT_EQ(holder.name(), "solo.b");
}

TEST(TopicThread, SinglePublisherRingLapsWithoutTearingAndCountsTheLoss) {
  PrivateNamespace ns;
  horus::Topic<Sample> pub("solo.lap", {.capacity = 8, .single_publisher = true});
  horus::Topic<Sample> sub("solo.lap");
  for (std::uint64_t i = 0; i < 20; ++i) {
    ASSERT_TRUE(pub.send(sealed<Sample>(i)));
  }
  for (std::uint64_t i = 12; i < 20; ++i) {
    auto msg = sub.try_recv();
    ASSERT_TRUE(msg.has_value());
    EXPECT_EQ(*msg, sealed<Sample>(i));
  }
  EXPECT_EQ(sub.lost(), 12u);
}

TEST(TopicThread, SinglePublisherWakesBlockedReceiversEveryTime) {
  PrivateNamespace ns;
  horus::Topic<Sample> ping("solo.ping", {.single_publisher = true});
  horus::Topic<Sample> pong("solo.pong", {.single_publisher = true});
  constexpr std::uint64_t kRounds = 2000;
  std::atomic<bool> ready{false};
  std::thread echo([&ready] {
    horus::Topic<Sample> in("solo.ping");
    horus::Topic<Sample> out("solo.pong");
    ready.store(true);
    for (std::uint64_t i = 0; i < kRounds; ++i) {
      auto msg = in.recv(20s);
      if (!msg || !out.send(*msg)) {
        return;
      }
    }
  });
  while (!ready.load()) {
    std::this_thread::yield();
  }
  std::uint64_t answered = 0;
  for (std::uint64_t i = 0; i < kRounds && answered == i; ++i) {
    EXPECT_TRUE(ping.send(sealed<Sample>(i)));
    auto reply = pong.recv(20s);
    EXPECT_TRUE(reply.has_value()) << "round " << i;
    answered += reply && *reply == sealed<Sample>(i) ? 1 : 0;
  }
  echo.join();
  EXPECT_EQ(answered, kRounds);
}

// The first handle to send numbers the tickets itself (the publisher lease); a second handle's
// send shares the ring. Nothing is lost or reordered on the way, and the holder's next send
// joins the shared claims.
TEST(TopicThread, ASecondPublisherSharesTheRingWithoutALossOrAStall) {
  PrivateNamespace ns;
  horus::Topic<Sample> first("shared");
  horus::Topic<Sample> second("shared");
  horus::Topic<Sample> sub("shared");
  for (std::uint64_t i = 0; i < 3; ++i) {
    ASSERT_TRUE(first.send(sealed<Sample>(i)));
  }
  ASSERT_TRUE(second.send(sealed<Sample>(100)));
  ASSERT_TRUE(first.send(sealed<Sample>(3)));
  ASSERT_TRUE(second.send(sealed<Sample>(101)));
  // Each arrives at once: a ticket left unwritten by the hand-over would hold the reader up.
  for (const std::uint64_t seq : {0, 1, 2, 100, 3, 101}) {
    auto msg = sub.try_recv();
    ASSERT_TRUE(msg.has_value()) << "waiting before " << seq;
    EXPECT_EQ(*msg, sealed<Sample>(seq));
  }
  EXPECT_FALSE(sub.try_recv().has_value());
  EXPECT_EQ(sub.lost(), 0u);
  EXPECT_EQ(first.stats().send_failures + second.stats().send_failures, 0u);
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].message_count, 6u);
  EXPECT_FALSE(topics[0].single_publisher);
}

// A loan taken under the lease is still its holder's to publish after the ring was shared, and
// a shared publisher going a whole lap round does not write over it meanwhile.
TEST(TopicThread, ALoanTakenUnderTheLeaseSurvivesTheHandOver) {
  PrivateNamespace ns;
  horus::Topic<Sample> first("handover", {.capacity = 8});
  horus::Topic<Sample> second("handover");
  horus::Topic<Sample> sub("handover");
  ASSERT_TRUE(first.send(sealed<Sample>(0)));
  auto msg = sub.try_recv();
  ASSERT_TRUE(msg.has_value());
  EXPECT_EQ(*msg, sealed<Sample>(0));
  auto loan = first.loan();
  topic_test::seal(*loan, 1);
  // Tickets 2 to 8; the 8th is a lap after ticket 0, in its slot, which was long committed.
  for (std::uint64_t seq = 2; seq < 9; ++seq) {
    ASSERT_TRUE(second.send(sealed<Sample>(seq)));
  }
  EXPECT_FALSE(second.send(sealed<Sample>(9))) << "this lap's slot holds the open loan";
  EXPECT_EQ(second.stats().send_failures, 1u);
  EXPECT_FALSE(sub.try_recv().has_value()) << "the loan's ticket comes first";
  ASSERT_TRUE(first.publish(std::move(loan)));
  for (std::uint64_t seq = 1; seq < 9; ++seq) {
    msg = sub.try_recv();
    ASSERT_TRUE(msg.has_value()) << seq;
    EXPECT_EQ(*msg, sealed<Sample>(seq));
  }
  EXPECT_EQ(sub.lost(), 0u);
}

// Publishers that start together race for the lease and for sharing the ring, while blocked
// receivers sleep across the hand-over; under ThreadSanitizer this checks the hand-over's
// ordering.
TEST(TopicThread, PublishersStartingTogetherShareTheRingWhileReceiversSleep) {
  PrivateNamespace ns;
  constexpr std::size_t kPublishers = 2;
  constexpr std::uint64_t kEach = 2000;
  horus::Topic<Sample> create("race", {.capacity = 8192});
  horus::Topic<Sample> sub("race");
  std::atomic<bool> go{false};
  std::atomic<int> failures{0};
  std::vector<std::thread> publishers;
  for (std::size_t p = 0; p < kPublishers; ++p) {
    publishers.emplace_back([p, &go, &failures] {
      horus::Topic<Sample> pub("race");
      while (!go.load()) {
        std::this_thread::yield();
      }
      for (std::uint64_t i = 0; i < kEach; ++i) {
        failures += pub.send(sealed<Sample>(i, p)) ? 0 : 1;
        if (i % 500 == 0) {
          std::this_thread::sleep_for(1ms);
        }
      }
    });
  }
  go.store(true);
  std::vector<std::uint64_t> next(kPublishers, 0);
  for (std::uint64_t got = 0; got < kPublishers * kEach; ++got) {
    auto msg = sub.recv(10s);
    ASSERT_TRUE(msg.has_value()) << "after " << got;
    std::size_t from = kPublishers;
    for (std::size_t p = 0; p < kPublishers; ++p) {
      if (msg->seq == next[p] && *msg == sealed<Sample>(msg->seq, p)) {
        from = p;
      }
    }
    ASSERT_LT(from, kPublishers) << "unexpected message " << msg->seq;
    ++next[from];
  }
  for (auto& thread : publishers) {
    thread.join();
  }
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(sub.lost(), 0u);
}

// A shared publisher preempted between the two stores of its commit (the slot's sequence, then
// its claim word) still holds the claim word a lap later, but its message is complete: the slot
// is free. A writer whose slot still shows it writing keeps the slot.
TEST(TopicThread, AWriterLateLettingGoOfItsSlotDoesNotHoldUpTheNextLap) {
  PrivateNamespace ns;
  horus::Topic<Sample> first("late", {.capacity = 8});
  horus::Topic<Sample> second("late");
  ASSERT_TRUE(first.send(sealed<Sample>(0)));
  // Shares the ring from ticket 1; ticket 8 lands in slot 0.
  for (std::uint64_t seq = 1; seq < 9; ++seq) {
    ASSERT_TRUE(second.send(sealed<Sample>(seq)));
  }
  // A second mapping of the segment plays the writers caught in the middle.
  const horus::detail::ShmSegment segment = horus::detail::ShmSegment::open_topic(
      "late",
      horus::detail::TypeDescriptor{
          horus::TypeInfo<Sample>::name, horus::TypeInfo<Sample>::fingerprint,
          horus::TypeInfo<Sample>::schema, true, sizeof(Sample), alignof(Sample)},
      horus::detail::SegmentOptions{8, 0, 0600, {}});
  const horus::detail::RingView& ring = segment.ring();
  const auto this_process = static_cast<std::uint32_t>(::getpid());
  ring.slot_claim(8).owner.store(this_process);
  ring.slot_claim(8).claim.store(2 * 8 + 1);
  for (std::uint64_t seq = 9; seq < 17; ++seq) {
    EXPECT_TRUE(second.send(sealed<Sample>(seq))) << seq;
  }
  EXPECT_EQ(second.stats().send_failures, 0u);
  EXPECT_EQ(first.read_latest()->seq, 16u);

  // Ticket 16's writer has marked the slot and not committed it: the next lap must wait.
  ring.slot_claim(16).claim.store(2 * 16 + 1);
  ring.slot(16).seq.store(2 * 16 + 1);
  for (std::uint64_t seq = 17; seq < 24; ++seq) {
    EXPECT_TRUE(second.send(sealed<Sample>(seq))) << seq;
  }
  EXPECT_FALSE(second.send(sealed<Sample>(24))) << "wrote over a slot being written";
  EXPECT_EQ(second.stats().send_failures, 1u);
}

}  // namespace
