// Topics, services, tensor pools, presence folders and log rings that other local users cannot
// plant, take over or write, with real users: the test (root, as CI runs it) creates them and runs
// each side in a forked child that switched to its user. A and B share the group horus_tg; M
// (horus_tm) is an outsider.
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
#include <vector>

#include <horus/detail/shm_segment.hpp>
#include <horus/error.hpp>
#include <horus/log.hpp>
#include <horus/presence.hpp>
#include <horus/service.hpp>
#include <horus/tensor_pool.hpp>
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

/// As `user`: opens tensor pool `name` of the test namespace with `mode`; 0 when it opened.
int open_pool_as(const char* user, const SharedRoot& root, const char* name, unsigned mode) {
  return as_user(user, root.path(), [&] {
    horus::TensorPoolOptions options;
    options.block_size = 4096;
    options.block_count = 2;
    options.mode = mode;
    options.namespace_name = SharedRoot::kNamespace;
    const horus::TensorPool pool = horus::TensorPool::open(name, options);
    return pool.stats().block_count == 2 ? 0 : 1;
  });
}

/// As `user`: 0 when opening tensor pool `name` with `mode` is refused with all of `expected`.
int pool_refused_as(const char* user, const SharedRoot& root, const char* name, unsigned mode,
                    std::initializer_list<std::string> expected) {
  return as_user(user, root.path(), [&] {
    horus::TensorPoolOptions options;
    options.block_size = 4096;
    options.block_count = 2;
    options.mode = mode;
    options.namespace_name = SharedRoot::kNamespace;
    return refused([&] { horus::TensorPool::open(name, options); }, expected);
  });
}

/// Runs `body` with stderr going to a pipe and returns what it wrote there (a few lines: the
/// pipe's buffer holds 64 KiB).
std::string stderr_of(const std::function<void()>& body) {
  int ends[2] = {-1, -1};
  if (::pipe(ends) != 0) return "<no pipe>";
  const int saved = ::dup(STDERR_FILENO);
  ::dup2(ends[1], STDERR_FILENO);
  ::close(ends[1]);
  body();
  ::dup2(saved, STDERR_FILENO);  // the pipe's last write end closes: the reads below see its end
  ::close(saved);
  std::string text;
  char buffer[4096];
  ssize_t got = 0;
  while ((got = ::read(ends[0], buffer, sizeof buffer)) > 0) {
    text.append(buffer, static_cast<std::size_t>(got));
  }
  ::close(ends[0]);
  return text;
}

std::size_t count_of(const std::string& text, const std::string& part) {
  std::size_t count = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) {
    ++count;
  }
  return count;
}

/// The line of `text` that holds `part` (empty if none).
std::string line_of(const std::string& text, const std::string& part) {
  const std::size_t at = text.find(part);
  if (at == std::string::npos) return {};
  const std::size_t start = text.rfind('\n', at);
  const std::size_t begin = start == std::string::npos ? 0 : start + 1;
  return text.substr(begin, text.find('\n', at) - begin);
}

/// 0 when `text` holds every one of `expected` exactly once, else 1 (printed).
int said_once(const std::string& text, std::initializer_list<std::string> expected) {
  for (const std::string& part : expected) {
    if (count_of(text, part) != 1) {
      std::fprintf(stdout, "'%s' is not said exactly once in: %s\n", part.c_str(), text.c_str());
      return 1;
    }
  }
  return 0;
}

constexpr const char* kPresenceWarning = "[horus] this process is not announced in namespace";
constexpr const char* kLogWarning = "[horus] logging to stderr only";

/// As `user`: opens two topics of the test namespace with `mode` and sends on them, and logs two
/// lines; 0 when everything worked and stderr held both lines and, exactly once each, the
/// presence and log warnings naming `path`s and `owner` (an empty `owner`: no warning expected).
int works_with_warnings_as(const char* user, const SharedRoot& root, unsigned mode,
                           const std::string& owner) {
  return as_user(user, root.path(), [&] {
    bool sent = false;
    std::uint64_t failures = 0;
    const std::string text = stderr_of([&] {
      horus::Topic<std::uint64_t> cmd("cmd", in_namespace(mode));
      horus::Topic<std::uint64_t> status("status", in_namespace(mode));
      sent = cmd.send(1) && status.send(2);
      horus::log::info("first line");
      horus::log::info("second line");
      horus::log::flush();
      failures = horus::detail::announcement_failures();
    });
    if (!sent) {
      std::fprintf(stdout, "%s could not send\n", user);
      return 1;
    }
    if (owner.empty()) {
      return failures == 0 && count_of(text, "[horus]") == 0 ? 0 : 1;
    }
    if (failures == 0) {
      std::fprintf(stdout, "no failed announcement counted\n");
      return 1;
    }
    return said_once(text, {"first line", "second line", kPresenceWarning,
                            root.path() + "/@presence", kLogWarning, root.path() + "/@logs"}) +
           said_once(line_of(text, kPresenceWarning), {owner}) +
           said_once(line_of(text, kLogWarning), {owner});
  });
}

/// Creates the empty file `path` (mode 0600) as `user`'s, where only root could put it.
bool plant_file_of(const char* user, const std::string& path) {
  const int planted = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  const bool owned =
      planted >= 0 && ::fchown(planted, uid_of(user), ::getgrnam(kGroup)->gr_gid) == 0;
  if (planted >= 0) ::close(planted);
  return owned;
}

bool empty_folder(const std::string& path) {
  return std::filesystem::is_directory(path) && std::filesystem::is_empty(path);
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
  // The test users' roots go too: nothing else of theirs is in them.
  std::filesystem::remove_all(root_a);
  std::filesystem::remove_all("/dev/shm/horus-" + std::to_string(uid_of(kUserM)));
}

TEST_F(ShmOwnership, ARootCreatedByAnotherUserIsRefusedNamingItsOwner) {
  SharedRoot parent;
  const std::string squatted = parent.path() + "/squatted";
  ASSERT_EQ(as_user(kUserM, "", [&] { return ::mkdir(squatted.c_str(), 0777) == 0 ? 0 : 1; }), 0);
  ::chmod(squatted.c_str(), 0777);
  EXPECT_EQ(refused_as(kUserA, squatted, "cmd", 0600, {squatted, kUserM, "HORUS_SHM_DIR"}), 0);
}

// The default root's name is known to every user, so anyone can take it first: the refusal names
// the owner and the way out (a root of one's own), which then works.
TEST_F(ShmOwnership, ASquattedDefaultRootIsRefusedWithTheWayOut) {
  const std::string victim_root = "/dev/shm/horus-" + std::to_string(uid_of(kUserB));
  std::filesystem::remove_all(victim_root);
  ASSERT_EQ(as_user(kUserM, "", [&] { return ::mkdir(victim_root.c_str(), 0700) == 0 ? 0 : 1; }),
            0);
  // 0700: the kernel refuses B before fstat could name the owner; the message still does.
  EXPECT_EQ(refused_as(kUserB, "", "cmd", 0600, {victim_root, kUserM, "HORUS_SHM_DIR"}), 0);
  ::chmod(victim_root.c_str(), 0755);
  EXPECT_EQ(refused_as(kUserB, "", "cmd", 0600, {victim_root, kUserM, "HORUS_SHM_DIR"}), 0);
  SharedRoot own;
  EXPECT_EQ(send_as(kUserB, own, "cmd", 0600, 1), 0) << "the way out the message names failed";
  std::filesystem::remove_all(victim_root);
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
  // B (in A's group) cannot write A's private folder, so the test (root) plants B's segment there.
  ASSERT_EQ(send_as(kUserA, root, "status", 0600, 1), 0);
  ASSERT_TRUE(plant_file_of(kUserB, root.segment("cmd")));
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0600, {root.segment("cmd"), kUserB}), 0);
}

// A's own folder or segment that its group can write was made for sharing: a handle that did not
// ask to share must not use it, or a group member could write what A means to keep private.
TEST_F(ShmOwnership, AGroupWritableObjectOfOwnIsRefusedWithoutSharing) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserA, root, "status", 0660, 1), 0);  // the folder is now group-writable
  EXPECT_EQ(refused_as(kUserA, root.path(), "cmd", 0600,
                       {root.folder(), "writable by group " + std::string(kGroup),
                        "did not ask to share"}),
            0);
  EXPECT_EQ(send_as(kUserA, root, "cmd", 0660, 1), 0) << "asking to share must work";

  SharedRoot private_root;
  ASSERT_EQ(send_as(kUserA, private_root, "cmd", 0600, 1), 0);
  ::chmod(private_root.segment("cmd").c_str(), 0660);
  EXPECT_EQ(refused_as(kUserA, private_root.path(), "cmd", 0600,
                       {private_root.segment("cmd"), "did not ask to share"}),
            0);
}

// A shared folder is sticky: a member can remove its own segments but not another member's.
TEST_F(ShmOwnership, AGroupMemberCannotRemoveAnotherMembersSegment) {
  SharedRoot root;
  ASSERT_EQ(send_as(kUserA, root, "cmd", 0660, 1), 0);
  ASSERT_EQ(send_as(kUserB, root, "other", 0660, 2), 0);
  EXPECT_EQ(as_user(kUserB, root.path(),
                    [&root] {
                      const bool refused =
                          ::unlink(root.segment("cmd").c_str()) != 0 && errno == EPERM;
                      const bool own_removed = ::unlink(root.segment("other").c_str()) == 0;
                      return refused && own_removed ? 0 : 1;
                    }),
            0);
  EXPECT_TRUE(std::filesystem::exists(root.segment("cmd")));
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
  EXPECT_EQ(info.st_mode & 07777, 03770U)
      << "a shared folder passes its group on (setgid) and keeps members' segments (sticky)";

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

TEST_F(ShmOwnership, ATensorPoolFolderCreatedByAnotherUserIsRefusedNamingItsOwner) {
  SharedRoot root;
  ASSERT_EQ(open_pool_as(kUserM, root, "camera", 0600), 0);
  const std::string pools = root.path() + "/@pool";
  ::chmod(pools.c_str(), 0777);
  EXPECT_EQ(pool_refused_as(kUserA, root, "camera", 0600, {pools, kUserM}), 0);
  EXPECT_EQ(pool_refused_as(kUserA, root, "other", 0600, {pools, kUserM}), 0);
}

TEST_F(ShmOwnership, ATensorPoolFileCreatedByAnotherUserIsRefusedWithoutGroupSharing) {
  SharedRoot root;
  // B (in A's group) cannot write A's private pool folder, so the test (root) plants B's file.
  ASSERT_EQ(open_pool_as(kUserA, root, "mine", 0600), 0);
  const std::string file = root.path() + "/@pool/" + SharedRoot::kNamespace + "/camera";
  ASSERT_TRUE(plant_file_of(kUserB, file));
  EXPECT_EQ(pool_refused_as(kUserA, root, "camera", 0600, {file, kUserB}), 0);
}

TEST_F(ShmOwnership, TwoUsersOfAGroupSharePoolsWhenBothAskForIt) {
  SharedRoot root;
  ASSERT_EQ(open_pool_as(kUserA, root, "shared", 0660), 0);
  ASSERT_EQ(open_pool_as(kUserB, root, "camera", 0660), 0);
  EXPECT_EQ(open_pool_as(kUserA, root, "camera", 0660), 0) << "the group-sharing case must work";
  EXPECT_EQ(pool_refused_as(kUserA, root, "other", 0600,
                            {root.path() + "/@pool", "did not ask to share"}),
            0)
      << "A did not ask to share (mode 0600) and still used the group's folder";
  EXPECT_EQ(pool_refused_as(kUserM, root, "camera", 0660, {root.path() + "/@pool"}), 0)
      << "a user outside the group reached the group's pool";
}

TEST_F(ShmOwnership, AWorldWritableTensorPoolIsRefusedAndCannotBeAskedFor) {
  SharedRoot root;
  ASSERT_EQ(open_pool_as(kUserA, root, "camera", 0600), 0);
  const std::string file = root.path() + "/@pool/" + SharedRoot::kNamespace + "/camera";
  ::chmod(file.c_str(), 0666);
  EXPECT_EQ(pool_refused_as(kUserA, root, "camera", 0600, {file, "writable by every user"}), 0);
  EXPECT_EQ(pool_refused_as(kUserA, root, "other", 0666, {"0666", "every local user"}), 0);
}

// Refusing would stop a robot over its bookkeeping: a squatted presence folder or log folder
// leaves the process unannounced and logging to stderr only, each said once on stderr with the
// path and its owner (and failed announcements counted), and nothing is written into them.
TEST_F(ShmOwnership, SquattedPresenceAndLogFoldersAreSkippedWithOneWarningEach) {
  SharedRoot root;
  for (const char* folder : {"/@presence", "/@logs"}) {
    const std::string path = root.path() + folder;
    ASSERT_EQ(as_user(kUserM, "", [&] { return ::mkdir(path.c_str(), 0777) == 0 ? 0 : 1; }), 0);
    ::chmod(path.c_str(), 0777);
  }
  EXPECT_EQ(works_with_warnings_as(kUserA, root, 0600, kUserM), 0);
  EXPECT_TRUE(empty_folder(root.path() + "/@presence"));
  EXPECT_TRUE(empty_folder(root.path() + "/@logs"));
}

TEST_F(ShmOwnership, AWorldWritableLogRingIsSkippedWithOneWarning) {
  SharedRoot root;
  ASSERT_EQ(works_with_warnings_as(kUserA, root, 0600, ""), 0);
  const std::string ring = root.path() + "/@logs/default";
  ASSERT_TRUE(std::filesystem::exists(ring));
  ::chmod(ring.c_str(), 0666);
  EXPECT_EQ(
      as_user(kUserA, root.path(),
              [&] {
                const std::string text = stderr_of([] {
                  horus::log::info("a line");
                  horus::log::flush();
                });
                return said_once(text, {kLogWarning, ring, "writable by every user", "a line"});
              }),
      0);
}

// In a root shared by a group, the presence registry and the log rings stay their creator's
// (documented in docs/shared-memory.md): a second user's processes share topics but are
// unannounced and log to stderr only, and say so once each, naming the first user.
TEST_F(ShmOwnership, InASharedRootASecondUsersPresenceAndLogsAreSkippedWithAWarning) {
  SharedRoot root;
  EXPECT_EQ(works_with_warnings_as(kUserA, root, 0660, ""), 0);
  EXPECT_EQ(works_with_warnings_as(kUserB, root, 0660, kUserA), 0);
}

}  // namespace
