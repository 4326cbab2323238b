// Who is in a session and which handles they hold (docs/api.md "Several editors"): the
// participants that watch or grab, and one lease per held handle. Leases coordinate editors
// who share the edit token; client ids are self-chosen, so this is not access control.
// Thread-safe; it never calls out while holding its lock.
#pragma once

#include "hdeform/v1/deform.pb.h"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace hdeform::service {

namespace pb = ::hdeform::v1;

class Roster {
 public:
  using Clock = std::chrono::steady_clock;
  struct Limits {
    std::size_t max_participants = 64;  // watchers and grabbers per session
    std::chrono::milliseconds default_lease{5000};
    std::chrono::milliseconds max_lease{60000};
  };
  explicit Roster(Limits limits) : limits_(limits) {}

  // A client's self-description (client_id, display_name, color): INVALID_ARGUMENT naming
  // the field, prefixed by `op`.
  static void check_participant(const pb::Participant& who, const char* op);

  // A client id belongs to the role that claimed it first (view or edit token), so a view
  // link cannot take an editor's identity: such a claim is ALREADY_EXISTS. An edit claim
  // takes over an id a viewer holds (the viewer's streams stop keeping it). Each binding
  // has a number (a claim) that join returns and leave takes.
  using Claim = std::uint64_t;

  // A watch stream of `who` opened; returns the claim its leave() must present.
  Claim join(const pb::Participant& who, bool editor);
  // That stream ended. When the binding's last stream ends its grabs end: a vanished client
  // holds nothing. A stream whose claim was taken over changes nothing (kDisplaced).
  enum class Left { kChanged, kAbsent, kDisplaced };
  Left leave(const std::string& client_id, Claim claim);

  // Takes `handles` (valid indices) for `who` until now + lease (0: the default). ABORTED
  // naming the holder if another client holds one of them (nothing is taken then).
  Clock::time_point grab(const pb::Participant& who, bool editor, const std::vector<int>& handles,
                         std::chrono::milliseconds lease, Clock::time_point now);
  // Ends `client_id`'s grabs of `handles` (empty: all of them). Returns whether any ended.
  bool release(const std::string& client_id, const std::vector<int>& handles);
  // An update from `client_id` (empty: anonymous) moving `handles`: ABORTED naming the
  // holder if another client holds one; renews the sender's own leases on them.
  void check_move(const std::string& client_id, const std::vector<int>& handles,
                  Clock::time_point now);
  // Ends the leases that ran out. Returns whether any did.
  bool expire(Clock::time_point now);
  // The handles were renumbered (new constraints): every grab ends.
  bool release_all();

  void describe(pb::Presence* out) const;
  // The display name `client_id` goes by, or went by lately ("anonymous" if unknown).
  std::string name_of(const std::string& client_id) const;
  bool empty() const;

 private:
  struct Member {
    std::string name, color;
    bool editor = false;  // the role that holds the id
    Claim claim = 0;
    int streams = 0;      // the binding's open watch streams
    std::map<int, std::pair<Clock::time_point, std::chrono::milliseconds>> held;  // until, lease
  };
  Member& member_locked(const pb::Participant& who, bool editor);
  void prune_locked(const std::string& client_id);  // drops a member with no stream, no grab
  // The holder of `handle` other than `client_id` whose lease is still running, or null.
  const std::pair<const std::string, Member>* other_holder_locked(
      int handle, const std::string& client_id, Clock::time_point now) const;
  [[noreturn]] void refuse_locked(int handle, const std::pair<const std::string, Member>& holder,
                                  Clock::time_point now, const char* what) const;

  const Limits limits_;
  mutable std::mutex mutex_;
  std::map<std::string, Member> members_;  // by client_id
  std::map<int, std::string> holder_;      // handle → client_id
  Claim next_claim_ = 1;
  // Names of clients seen lately, kept after they leave: history steps name their authors.
  std::map<std::string, std::string> seen_names_;  // at most kMaxSeenNames
};

}  // namespace hdeform::service
