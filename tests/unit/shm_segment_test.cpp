// Segments that cannot be trusted: every opener validates the headers before using them.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <string>

#include <horus/detail/process.hpp>
#include <horus/detail/shm_segment.hpp>
#include <horus/topic.hpp>
#include <horus/topic_registry.hpp>
#include <topic_test/sample.hpp>

#include "topic_test_support.hpp"

namespace {

using horus::detail::kControlSize;
using horus::detail::LayoutHeader;
using topic_test::PrivateNamespace;
using topic_test::Sample;

std::string segment_path(const PrivateNamespace& ns, const std::string& topic) {
  return horus::detail::namespace_directory(ns.name()) + "/" + topic;
}

void create(const std::string& topic) {
  horus::Topic<Sample> data(topic);
  data.send(Sample{});
}

void overwrite(const std::string& path, std::size_t offset, std::uint64_t value) {
  const int fd = ::open(path.c_str(), O_WRONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::pwrite(fd, &value, sizeof value, static_cast<off_t>(offset)),
            static_cast<ssize_t>(sizeof value));
  ::close(fd);
}

std::string open_error(const std::string& topic) {
  try {
    horus::Topic<Sample> data(topic);
  } catch (const horus::Error& e) {
    return e.what();
  }
  return "";
}

TEST(ShmSegment, TruncatedSegmentIsAnErrorNotSigbus) {
  PrivateNamespace ns;
  create("cut");
  ASSERT_EQ(::truncate(segment_path(ns, "cut").c_str(), kControlSize + 1000), 0);
  const std::string error = open_error("cut");
  EXPECT_NE(error.find("corrupt"), std::string::npos) << error;
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_NE(topics[0].error.find("truncated"), std::string::npos) << topics[0].error;
}

TEST(ShmSegment, SegmentShorterThanItsControlPageIsAnError) {
  PrivateNamespace ns;
  create("stub");
  ASSERT_EQ(::truncate(segment_path(ns, "stub").c_str(), 100), 0);
  EXPECT_NE(open_error("stub").find("truncated"), std::string::npos);
}

TEST(ShmSegment, CorruptControlMagicIsAnError) {
  PrivateNamespace ns;
  create("magic");
  overwrite(segment_path(ns, "magic"), 0, 0x1234);
  EXPECT_NE(open_error("magic").find("control magic"), std::string::npos);
}

TEST(ShmSegment, AnotherFormatVersionIsRefusedAndLeftAlone) {
  PrivateNamespace ns;
  create("other_version");
  const std::string path = segment_path(ns, "other_version");
  overwrite(path, offsetof(horus::detail::ControlBlock, version),
            std::uint64_t{kControlSize} << 32 | (horus::detail::kSegmentVersion - 1));
  const std::string error = open_error("other_version");
  EXPECT_NE(error.find("unsupported version " + std::to_string(horus::detail::kSegmentVersion - 1)),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("remove the file"), std::string::npos) << error;
  EXPECT_EQ(::access(path.c_str(), F_OK), 0) << "a segment of another format was removed";
}

TEST(ShmSegment, AProcessIsItsPidAndWhenItStarted) {
  using horus::detail::identity_alive;
  using horus::detail::identity_pid;
  const std::uint64_t me = horus::detail::this_process_identity();
  EXPECT_EQ(identity_pid(me), static_cast<std::uint32_t>(::getpid()));
  EXPECT_NE(me >> 32, 0u) << "the start time was not read";
  EXPECT_TRUE(identity_alive(me));
  EXPECT_FALSE(identity_alive(me + (std::uint64_t{1} << 32)))
      << "a process started at another time is another process with the same pid";
  EXPECT_TRUE(identity_alive(identity_pid(me))) << "an unknown start time goes by the pid";
  EXPECT_FALSE(identity_alive(0));

  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::uint64_t own = horus::detail::this_process_identity();
    ::_exit(identity_pid(own) == static_cast<std::uint32_t>(::getpid()) && own != me ? 0 : 1);
  }
  siginfo_t exited{};
  ASSERT_EQ(::waitid(P_PID, static_cast<id_t>(child), &exited, WEXITED | WNOWAIT), 0);
  EXPECT_EQ(exited.si_status, 0) << "a forked child kept its parent's identity";
  EXPECT_TRUE(horus::detail::process_alive(static_cast<std::uint32_t>(child)))
      << "kill(pid, 0) no longer finds an unreaped child";
  EXPECT_FALSE(identity_alive(static_cast<std::uint32_t>(child))) << "a zombie has exited";
  ::waitpid(child, nullptr, 0);
}

TEST(ShmSegment, InvalidPublisherModeIsAnError) {
  PrivateNamespace ns;
  create("mode");
  overwrite(segment_path(ns, "mode"),
            offsetof(horus::detail::ControlBlock, ring) +
                offsetof(horus::detail::RingControl, single_publisher),
            7);
  EXPECT_NE(open_error("mode").find("invalid publisher mode 7"), std::string::npos);
}

TEST(ShmSegment, CorruptGeometryIsAnError) {
  PrivateNamespace ns;
  create("geometry");
  overwrite(segment_path(ns, "geometry"), kControlSize + offsetof(LayoutHeader, capacity), 3);
  EXPECT_NE(open_error("geometry").find("invalid capacity"), std::string::npos);
}

TEST(ShmSegment, SlotStrideBeyondTheFileIsAnError) {
  PrivateNamespace ns;
  create("stride");
  overwrite(segment_path(ns, "stride"), kControlSize + offsetof(LayoutHeader, slot_stride),
            std::uint64_t{1} << 40);
  EXPECT_NE(open_error("stride").find("corrupt"), std::string::npos);
}

TEST(ShmSegment, HugeSchemaSizeIsAnError) {
  PrivateNamespace ns;
  create("schema");
  overwrite(segment_path(ns, "schema"), kControlSize + offsetof(LayoutHeader, schema_size),
            ~std::uint64_t{0});
  EXPECT_NE(open_error("schema").find("corrupt"), std::string::npos);
}

TEST(ShmSegment, ClaimsOffsetOutsideTheFileIsAnError) {
  PrivateNamespace ns;
  create("claims");
  overwrite(segment_path(ns, "claims"), kControlSize + offsetof(LayoutHeader, claims_offset),
            ~std::uint64_t{0} - 63);
  EXPECT_NE(open_error("claims").find("invalid schema or slot offsets"), std::string::npos);
}

TEST(ShmSegment, DescriptionOutsideItsPlaceIsAnError) {
  PrivateNamespace ns;
  create("described");
  overwrite(segment_path(ns, "described"), kControlSize + offsetof(LayoutHeader, description_size),
            ~std::uint64_t{0});
  EXPECT_NE(open_error("described").find("invalid type description"), std::string::npos);
}

// Publishers' claim words sit apart from every line a subscriber reads (and from its
// neighbour, which the adjacent-line prefetcher pulls in); a payload that does not fit beside
// the sequence word starts on the next line, so writing it never disturbs a polling reader.
TEST(ShmSegment, ClaimWordsLiveApartFromTheSlots) {
  PrivateNamespace ns;
  create("layout");
  const int fd = ::open(segment_path(ns, "layout").c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  LayoutHeader header{};
  ASSERT_EQ(::pread(fd, &header, sizeof header, kControlSize), static_cast<ssize_t>(sizeof header));
  ::close(fd);
  const std::uint64_t claims_end =
      header.claims_offset + header.capacity * sizeof(horus::detail::SlotClaim);
  EXPECT_GE(header.slots_offset, claims_end + 2 * horus::detail::kCacheLine);
  ASSERT_EQ(sizeof(Sample), 64u);
  EXPECT_EQ(header.payload_offset, horus::detail::kCacheLine);
  EXPECT_EQ(header.slot_stride, 2 * horus::detail::kCacheLine);
}

TEST(ShmSegment, CleanRemovesOnlySegmentsWithoutLiveUsers) {
  PrivateNamespace ns;
  create("abandoned");
  horus::Topic<Sample> used("used");
  EXPECT_EQ(horus::clean_namespace(), 1u);
  const auto topics = horus::list_topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].name, "used");
}

}  // namespace
