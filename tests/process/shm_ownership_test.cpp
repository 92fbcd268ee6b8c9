// Topics that other local users cannot plant, take over or write, with real users: the test
// (root, as CI runs it) creates them and runs each side in a forked child that switched to its
// user. A and B share the group horus_tg; M (horus_tm) is an outsider.
#include <fcntl.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <pwd.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include <horus/detail/shm_segment.hpp>
#include <horus/error.hpp>
#include <horus/service.hpp>
#include <horus/topic.hpp>
#include <kv_example/key_value_store.hpp>

namespace {

constexpr const char* kGroup = "horus_tg";
constexpr const char* kUserA = "horus_ta";
constexpr const char* kUserB = "horus_tb";
constexpr const char* kUserM = "horus_tm";

/// Runs a command (no shell) and returns its exit status.
int run(const std::vector<std::string>& command) {
  const pid_t child = ::fork();
  if (child == 0) {
    std::vector<char*> argv;
    for (const std::string& arg : command) {
      argv.push_back(const_cast<char*>(arg.c_str()));
    }
    argv.push_back(nullptr);
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// Creates a user unless it exists.
bool ensure_user(const std::vector<std::string>& useradd, const char* name) {
  return ::getpwnam(name) != nullptr || (run(useradd) == 0 && ::getpwnam(name) != nullptr);
}

/// Why root could not create the users, or empty once they exist. Test cases run in parallel
/// processes: one at a time creates what is missing (concurrent useradd calls undo each other's
/// work).
std::string ensure_users() {
  const int lock = ::open("/tmp/horus_shm_ownership_test.lock", O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (lock < 0 || ::flock(lock, LOCK_EX) != 0) {
    return "cannot lock /tmp/horus_shm_ownership_test.lock to create the test users";
  }
  const std::string nologin = "/usr/sbin/nologin";
  const bool group = ::getgrnam(kGroup) != nullptr || run({"/usr/sbin/groupadd", kGroup}) == 0;
  const bool ready =
      group &&
      ensure_user({"/usr/sbin/useradd", "-M", "-N", "-g", kGroup, "-s", nologin, kUserA}, kUserA) &&
      ensure_user({"/usr/sbin/useradd", "-M", "-N", "-g", kGroup, "-s", nologin, kUserB}, kUserB) &&
      ensure_user({"/usr/sbin/useradd", "-M", "-U", "-s", nologin, kUserM}, kUserM);
  ::close(lock);
  return ready ? std::string() : "could not create the test users with groupadd/useradd";
}

uid_t uid_of(const char* user) { return ::getpwnam(user)->pw_uid; }

/// Runs `side` in a forked child switched to `user` (its groups, then its ids), with
/// HORUS_SHM_DIR = `root` (unset when empty). Returns its exit status; messages go to stderr.
int as_user(const char* user, const std::string& root, const std::function<int()>& side) {
  const passwd* entry = ::getpwnam(user);
  if (entry == nullptr) {
    return -3;
  }
  const uid_t uid = entry->pw_uid;
  const gid_t gid = entry->pw_gid;
  const pid_t child = ::fork();
  if (child == 0) {
    if (::initgroups(user, gid) != 0 || ::setgid(gid) != 0 || ::setuid(uid) != 0) {
      ::_exit(120);
    }
    if (root.empty()) {
      ::unsetenv("HORUS_SHM_DIR");
    } else {
      ::setenv("HORUS_SHM_DIR", root.c_str(), 1);
    }
    int status = 121;
    try {
      status = side();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: unexpected error: %s\n", user, e.what());
    }
    ::_exit(status);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/// 0 when `open` throws horus::Error whose text holds every one of `expected`, else 1 (printed).
int refused(const std::function<void()>& open, std::initializer_list<std::string> expected) {
  try {
    open();
  } catch (const horus::Error& e) {
    const std::string text = e.what();
    for (const std::string& part : expected) {
      if (text.find(part) == std::string::npos) {
        std::fprintf(stderr, "error lacks '%s': %s\n", part.c_str(), text.c_str());
        return 1;
      }
    }
    return 0;
  }
  std::fprintf(stderr, "opened what it should have refused\n");
  return 1;
}

/// A root shared by every user, sticky like /tmp (what a machine-wide HORUS_SHM_DIR would be),
/// private to one test and removed after it.
class SharedRoot {
 public:
  SharedRoot() {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = "/dev/shm/horus-test-" + std::to_string(::getpid()) + "-" + test->name();
    std::filesystem::remove_all(path_);
    ::mkdir(path_.c_str(), 0700);
    ::chmod(path_.c_str(), 01777);
  }
  SharedRoot(const SharedRoot&) = delete;
  SharedRoot& operator=(const SharedRoot&) = delete;
  ~SharedRoot() { std::filesystem::remove_all(path_); }
  const std::string& path() const { return path_; }
  std::string folder() const { return path_ + "/" + kNamespace; }
  std::string segment(const std::string& topic) const { return folder() + "/" + topic; }

  static constexpr const char* kNamespace = "robot";

 private:
  std::string path_;
};

horus::TopicOptions in_namespace(unsigned mode = 0600) {
  horus::TopicOptions options;
  options.namespace_name = SharedRoot::kNamespace;
  options.mode = mode;
  return options;
}

/// As `user`: opens topic `name` of the test namespace with `mode` and sends `value`.
int send_as(const char* user, const SharedRoot& root, const char* name, unsigned mode,
            std::uint64_t value) {
  return as_user(user, root.path(), [&] {
    horus::Topic<std::uint64_t> topic(name, in_namespace(mode));
    return topic.send(value) ? 0 : 1;
  });
}

/// As `user`: 0 when opening topic `name` with `mode` is refused with all of `expected`.
int refused_as(const char* user, const std::string& root, const char* name, unsigned mode,
               std::initializer_list<std::string> expected) {
  return as_user(user, root, [&] {
    return refused([&] { horus::Topic<std::uint64_t>(name, in_namespace(mode)); }, expected);
  });
}

class ShmOwnership : public ::testing::Test {
 protected:
  // Only a run that cannot create users may skip; as root (CI), failing to create them fails.
  void SetUp() override {
    if (::geteuid() != 0) {
      GTEST_SKIP() << "needs root to create users and switch to them (CI runs as root)";
    }
    if (const std::string why = ensure_users(); !why.empty()) {
      FAIL() << why;
    }
  }
};

TEST_F(ShmOwnership, EachUserHasAPrivateRootByDefault) {
  const std::string ns = "ownership_" + std::to_string(::getpid());
  horus::TopicOptions options;
  options.namespace_name = ns;
  const auto open_and_send = [&options](std::uint64_t value) {
    horus::Topic<std::uint64_t> cmd("cmd", options);
    return cmd.send(value) ? 0 : 1;
  };
  ASSERT_EQ(as_user(kUserA, "", [&] { return open_and_send(1); }), 0);
  ASSERT_EQ(as_user(kUserM, "", [&] { return open_and_send(666); }), 0);
  EXPECT_EQ(as_user(kUserA, "",
                    [&] {
                      const horus::Topic<std::uint64_t> cmd("cmd", options);
                      return cmd.read_latest() == std::optional<std::uint64_t>(1) ? 0 : 1;
                    }),
            0)
      << "another user's send reached this user's topic";
  const std::string root_a = "/dev/shm/horus-" + std::to_string(uid_of(kUserA));
  struct stat info {};
  ASSERT_EQ(::lstat(root_a.c_str(), &info), 0);
  EXPECT_EQ(info.st_uid, uid_of(kUserA));
  EXPECT_EQ(info.st_mode & 07777, 0700U);
  std::filesystem::remove_all(root_a + "/" + ns);
  std::filesystem::remove_all("/dev/shm/horus-" + std::to_string(uid_of(kUserM)) + "/" + ns);
}

TEST_F(ShmOwnership, ARootCreatedByAnotherUserIsRefusedNamingItsOwner) {
  SharedRoot parent;
  const std::string squatted = parent.path() + "/squatted";
  ASSERT_EQ(as_user(kUserM, "", [&] { return ::mkdir(squatted.c_str(), 0777) == 0 ? 0 : 1; }), 0);
  ::chmod(squatted.c_str(), 0777);
  EXPECT_EQ(refused_as(kUserA, squatted, "cmd", 0600, {squatted, kUserM}), 0);
}

TEST_F(ShmOwnership, ANamespaceFolderCreatedByAnotherUserIsRefusedNamingItsOwner) {
  SharedRoot root;
  // M is first after a reboot: it creates the robot's namespace and a topic in it, and opens the
  // folder to everyone (0777, as in the report).
  ASSERT_EQ(send_as(kUserM, root, "cmd", 0600, 666), 0);
  ::chmod(root.folder().c_str(), 0777);
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0600, {root.folder(), kUserM}), 0);
  // Not writable by A, but still M's: its segments would be M's to write.
  ::chmod(root.folder().c_str(), 0755);
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0600, {root.folder(), kUserM}), 0);
}

TEST_F(ShmOwnership, ASegmentCreatedByAnotherUserIsRefusedWithoutGroupSharing) {
  SharedRoot root;
  // A shares one topic with its group, so its namespace folder is group-writable; B (in the
  // group) plants the topic A will open privately.
  ASSERT_EQ(send_as(kUserA, root, "status", 0660, 1), 0);
  ASSERT_EQ(send_as(kUserB, root, "cmd", 0660, 666), 0);
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0600, {root.segment("cmd"), kUserB}), 0);
}

TEST_F(ShmOwnership, AWorldWritableSegmentIsRefusedAndCannotBeAskedFor) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserA, root, "cmd", 0600, 1), 0);
  ::chmod(root.segment("cmd").c_str(), 0666);
  EXPECT_EQ(
      refused_as(kUserA, root.path(), "cmd", 0600, {root.segment("cmd"), "writable by every user"}),
      0);
  EXPECT_EQ(refused_as(kUserA, root.path(), "other", 0666, {"0666", "every local user"}), 0);
}

TEST_F(ShmOwnership, ASymbolicLinkInPlaceOfASegmentIsRefused) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserA, root, "status", 0660, 1), 0);
  ASSERT_EQ(as_user(kUserB, root.path(),
                    [&root] {
                      return ::symlink(root.segment("status").c_str(), root.segment("cmd").c_str());
                    }),
            0);
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0660, {root.segment("cmd"), "symbolic link"}),
            0);
}

TEST_F(ShmOwnership, TwoUsersOfAGroupShareTopicsWhenBothAskForIt) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserA, root, "cmd", 0660, 1), 0);
  struct stat info {};
  ASSERT_EQ(::stat(root.segment("cmd").c_str(), &info), 0);
  EXPECT_EQ(info.st_gid, ::getgrnam(kGroup)->gr_gid);
  EXPECT_EQ(info.st_mode & 0777, 0660U);
  ASSERT_EQ(::stat(root.folder().c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 07777, 02770U) << "a shared folder passes its group on (setgid)";

  EXPECT_EQ(send_as(kUserB, root, "cmd", 0660, 42), 0);
  EXPECT_EQ(as_user(kUserA, root.path(),
                    [] {
                      const horus::Topic<std::uint64_t> cmd("cmd", in_namespace(0660));
                      return cmd.read_latest() == std::optional<std::uint64_t>(42) ? 0 : 1;
                    }),
            0)
      << "a group member's send did not arrive";
  EXPECT_EQ(refused_as(kUserB, root.path(), "cmd", 0600, {root.folder(), kUserA}), 0)
      << "B did not ask to share (mode 0600) and still took A's topic";
  EXPECT_EQ(refused_as(kUserM, root.path(), "cmd", 0660, {root.folder()}), 0)
      << "a user outside the group reached the group's topics";
}

TEST_F(ShmOwnership, AServiceInASquattedNamespaceIsRefused) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserM, root, "bait", 0600, 1), 0);
  ::chmod(root.folder().c_str(), 0777);
  EXPECT_EQ(
      as_user(kUserA, root.path(),
              [&root] {
                return refused(
                           [] {
                             horus::ServiceServerBuilder<kv_example::KeyValueStore>()
                                 .on_request([](const kv_example::KeyValueStoreRequest&) {
                                   return kv_example::KeyValueStoreResponse{};
                                 })
                                 .options(in_namespace())
                                 .build();
                           },
                           {root.folder(), kUserM}) +
                       refused(
                           [] {
                             horus::ServiceClient<kv_example::KeyValueStore> client(in_namespace());
                           },
                           {root.folder(), kUserM});
              }),
      0);
}

}  // namespace
