#include "access.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <sstream>
#include <system_error>

#include "horus/error.hpp"

namespace horus::view {

namespace {

std::string octal_mode(mode_t mode) {
  char text[8];
  std::snprintf(text, sizeof(text), "%04o", static_cast<unsigned>(mode & 07777));
  return text;
}

/// Safe from any thread (std::strerror may share one buffer).
std::string errno_text(int error) { return std::generic_category().message(error); }

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// `text` with its %XX escapes (and '+', a form's space) decoded; a malformed escape stays as
/// it is (it matches no token).
std::string percent_decoded(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%' && i + 2 < text.size() && hex_digit(text[i + 1]) >= 0 &&
        hex_digit(text[i + 2]) >= 0) {
      out += static_cast<char>(hex_digit(text[i + 1]) * 16 + hex_digit(text[i + 2]));
      i += 2;
    } else {
      out += text[i] == '+' ? ' ' : text[i];
    }
  }
  return out;
}

/// Whether `a` and `b` are equal, in a time that depends only on their lengths.
bool same_secret(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  unsigned char differ = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    differ |= static_cast<unsigned char>(a[i] ^ b[i]);
  }
  return differ == 0;
}

}  // namespace

PeerTokens PeerTokens::load(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    throw Error("cannot read the tokens file " + path + ": " + errno_text(errno));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat status {};
  if (::fstat(fd, &status) != 0) {
    throw Error("cannot read the tokens file " + path + ": " + errno_text(errno));
  }
  if (!S_ISREG(status.st_mode)) {
    throw Error("the tokens file " + path + " is not a regular file");
  }
  if (status.st_uid != ::geteuid()) {
    throw Error("the tokens file " + path + " is owned by uid " + std::to_string(status.st_uid) +
                ", not by this user (uid " + std::to_string(::geteuid()) +
                "): whoever owns it can change who gets in");
  }
  if ((status.st_mode & 077) != 0) {
    throw Error("the tokens file " + path + " has mode " + octal_mode(status.st_mode) +
                ": group or others may read or change its tokens; chmod 600 " + path);
  }
  std::string text;
  char buffer[4096];
  for (;;) {
    const ssize_t got = ::read(fd, buffer, sizeof(buffer));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) throw Error("cannot read the tokens file " + path + ": " + errno_text(errno));
    if (got == 0) break;
    text.append(buffer, static_cast<std::size_t>(got));
  }
  return parse(text, path);
}

PeerTokens PeerTokens::parse(std::string_view text, const std::string& where) {
  PeerTokens tokens;
  std::istringstream lines{std::string(text)};
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::string at = where + ":" + std::to_string(number) + ": ";
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream words(line);
    std::string peer;
    std::string token;
    std::string extra;
    words >> peer >> token;
    if (token.empty() || (words >> extra)) {
      throw Error(at + "'" + line + "' is not 'PEER TOKEN'");
    }
    if (token.size() < kShortestToken) {
      throw Error(at + "the token of '" + peer + "' is " + std::to_string(token.size()) +
                  " characters, fewer than " + std::to_string(kShortestToken) +
                  " (make one with: openssl rand -hex 16)");
    }
    for (const Entry& entry : tokens.entries_) {
      if (entry.token == token) {
        throw Error(at + "the token of '" + peer + "' is also the token of '" + entry.peer +
                    "': each token names one peer");
      }
    }
    tokens.entries_.push_back(Entry{peer, token});
  }
  return tokens;
}

std::optional<std::string> PeerTokens::peer_of(std::string_view token) const {
  std::optional<std::string> found;
  for (const Entry& entry : entries_) {
    if (same_secret(entry.token, token) && !found) found = entry.peer;
  }
  return found;
}

std::optional<std::string> token_of_target(std::string_view target) {
  const auto query_start = target.find('?');
  if (query_start == std::string_view::npos) return std::nullopt;
  std::string_view query = target.substr(query_start + 1);
  query = query.substr(0, query.find('#'));
  while (!query.empty()) {
    const auto end = query.find('&');
    const std::string_view parameter = query.substr(0, end);
    const auto equals = parameter.find('=');
    if (percent_decoded(parameter.substr(0, equals)) == "token") {
      return equals == std::string_view::npos ? std::string()
                                              : percent_decoded(parameter.substr(equals + 1));
    }
    if (end == std::string_view::npos) break;
    query = query.substr(end + 1);
  }
  return std::nullopt;
}

}  // namespace horus::view
