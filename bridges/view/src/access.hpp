// Who a live view's client is (README.md, Access): the tokens file that names a peer per token,
// and the token a client's URL carries. The policy of what each peer may do is the bridges'
// own (horus::bridge::PeerPolicy); the client certificates are TLS's (horus/bridge/tls.hpp).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace horus::view {

/// Peers by token, from lines "PEER TOKEN" (blank lines and lines starting with # skipped).
class PeerTokens {
 public:
  /// A token shorter than this is refused: it could be guessed.
  static constexpr std::size_t kShortestToken = 16;

  /// The file at `path`, which this user must own and neither group nor others may read
  /// (checked on the opened file). Throws horus::Error naming the file and what is wrong, or
  /// the line and why for a malformed one.
  static PeerTokens load(const std::string& path);
  /// `text` as a tokens file's content; `where` names it in errors ("FILE:LINE: ...").
  static PeerTokens parse(std::string_view text, const std::string& where);

  /// The peer `token` names; none for an unknown token. Takes as long for any token of a given
  /// length, whichever (if any) it matches.
  std::optional<std::string> peer_of(std::string_view token) const;
  std::size_t size() const noexcept { return entries_.size(); }

 private:
  struct Entry {
    std::string peer;
    std::string token;
  };
  std::vector<Entry> entries_;
};

/// The value of `token` in the query of a request target ("/?token=abc%21&x=1" gives "abc!");
/// none when there is no token parameter.
std::optional<std::string> token_of_target(std::string_view target);

}  // namespace horus::view
