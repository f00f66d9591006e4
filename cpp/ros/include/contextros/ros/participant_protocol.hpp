// A context node's side of the Layer manager protocol (docs/protocol.md), as a pure state
// machine: events in, actions out, time passed in; no ROS, no I/O, no threads. It is the
// C++ twin of src/contextros/protocol/participant.py and decides exactly as that does:
// which manager states to apply (only ones newer than anything applied, scheduled or
// refused, so a reordered or duplicated message never takes the node back) and what to
// report. A state deferred by a critical section is reported as pending and acknowledged
// (applied_epoch) only once the runtime has really applied it.
//
// On a lossy link every report may be lost: a new report is repeated shortly after it was
// first sent (`repeats`), and the heartbeat repeats it anyway. The manager's own heartbeat
// tells the participant it is still connected; silent for `manager_timeout`, the node knows
// it is cut off (ManagerLost) and may fall back to a safe configuration. Every state from
// the network is checked first (state_problems: the rules of
// src/contextros/protocol/validation.py).
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "contextros/layer.hpp"

namespace contextros::ros {

using Clock = std::chrono::steady_clock;

// The manager's layer state: a numbered full snapshot (last layer = outermost).
struct LayerState {
  std::uint64_t epoch = 0;
  std::vector<std::string> active;
  std::string requester;
  std::string reason;
  std::string manager_id;
  // When the manager published it (wall clock, seconds since 1970); not part of identity.
  double stamp = 0.0;
  // Sent with it, not part of it: the heartbeat period (seconds) the manager asks of its
  // participants while nothing changes; 0: their own.
  double status_period = 0.0;
};

// What a participant tells the manager (ParticipantStatus without the wall-clock stamp).
struct ParticipantReport {
  std::string node;
  std::string incarnation;
  std::vector<LayerInfo> layers;
  std::uint64_t applied_epoch = 0;
  std::vector<std::string> active;
  std::string applied_manager_id;
  bool in_critical_section = false;
  std::uint64_t pending_epoch = 0;
  std::uint64_t failed_epoch = 0;
  std::string error;
  bool leaving = false;
  std::vector<std::string> hosted;  // other nodes of the process it speaks for
  bool manager_lost = false;         // the manager was not heard for manager_timeout
  // The last vote on an atomic activation: the proposed epoch (0: none), the manager that
  // proposed it, yes or no, and why not.
  std::uint64_t vote_epoch = 0;
  std::string vote_manager_id;
  bool vote_yes = false;
  std::string vote_reason;
};

// Make this state the process's decisive configuration (the runtime's set_active).
struct ApplyState {
  LayerState state;
};
// Send this report to the manager.
struct PublishStatus {
  ParticipantReport report;
};
// A state message failed validation and was ignored (log it).
struct StateRejected {
  std::vector<std::string> problems;
};
// The manager was not heard for the liveness bound; the node keeps its configuration.
struct ManagerLost {
  Clock::duration silent_for;
};
// A manager is heard again.
struct ManagerFound {
  std::string manager_id;
};
using ParticipantAction =
    std::variant<ApplyState, PublishStatus, StateRejected, ManagerLost, ManagerFound>;
using ParticipantActions = std::vector<ParticipantAction>;

inline constexpr std::chrono::milliseconds default_heartbeat_period{250};
inline constexpr std::chrono::milliseconds default_manager_timeout{3000};
// The leaving report is best effort like every report: the participant sends it again this
// much later, which also lets the first copy leave the process before its writer goes.
inline constexpr std::chrono::milliseconds leave_repeat_after{50};
inline const std::vector<Clock::duration> default_repeats{std::chrono::milliseconds(50),
                                                          std::chrono::milliseconds(150)};
// Reports are repeated shortly after a change only while the link shows loss: this long
// after the manager was last heard late (more than 1.6 heartbeat periods after the
// message before). On a clean link the repeats only load the manager.
inline constexpr std::chrono::seconds loss_memory{30};
// The longest heartbeat period a manager's message can ask for (a forged one must not
// silence a node for long).
inline constexpr std::chrono::seconds max_status_period{60};
// Epochs beyond 2**48 are never issued by an honest manager (docs/protocol.md).
inline constexpr std::uint64_t max_epoch = std::uint64_t{1} << 48;

// What is wrong with a state received from the network (empty: nothing).
std::vector<std::string> state_problems(const LayerState& state);
// Every relation the configuration `active` breaks among these declarations, as sentences
// (the same sentences as src/contextros/protocol/relations.py).
std::vector<std::string> relation_violations(const std::vector<std::string>& active,
                                             const std::vector<LayerInfo>& declarations);

class ParticipantProtocol {
 public:
  ParticipantProtocol(std::string node, std::string incarnation, std::vector<LayerInfo> layers,
                      Clock::duration heartbeat_period = default_heartbeat_period,
                      Clock::duration manager_timeout = default_manager_timeout,
                      std::vector<Clock::duration> repeats = default_repeats);

  // Carry on for the process from `previous`, the participant this one replaces (its node
  // went, another node of the process carries the participant now): its applied epoch,
  // layers, failure and manager. Call it before announce(). A switch `previous` deferred is
  // not carried (its acknowledgement went with it): the manager's states bring it again.
  void continue_from(const ParticipantProtocol& previous);

  // -- events --------------------------------------------------------------------------
  ParticipantActions announce(Clock::time_point now);
  // A state from the manager (reliable topic or heartbeat): apply it if newer. Without
  // `now` it does not count as hearing the manager.
  ParticipantActions receive_state(const LayerState& state,
                                   std::optional<Clock::time_point> now = std::nullopt);
  // An atomic activation asks whether this node can apply `proposal`: vote once per
  // (epoch, manager). Yes: no critical section open or deferring a switch, no relation this
  // node declares broken, and `veto` (the application's answer) empty. A vote changes
  // nothing: the node switches only when the manager commits that epoch as a state.
  // `vote` false: the proposal only shows the manager is alive (the adapter is still asking
  // the application's vetoes about it).
  ParticipantActions receive_proposal(const LayerState& proposal, Clock::time_point now,
                                      std::string_view veto = {}, bool vote = true);
  // Whether receive_proposal would vote on `proposal` (new, valid, not voted on yet): the
  // adapter asks the application's vetoes once per proposal, not on each repeat.
  bool wants_vote(const LayerState& proposal) const;
  // The runtime applied `state` (at once, or when a critical section closed).
  ParticipantActions applied(const LayerState& state, Clock::time_point now);
  // The runtime queued `state` behind an open critical section.
  ParticipantActions deferred(const LayerState& state, Clock::time_point now);
  // The runtime refused `state` (say, a local relation the manager did not know).
  ParticipantActions failed(const LayerState& state, std::string_view error, Clock::time_point now);
  // Speak for these other nodes of the process, implementing these layers in all.
  ParticipantActions host(std::vector<std::string> hosted, std::vector<LayerInfo> layers,
                          Clock::time_point now);
  ParticipantActions tick(Clock::time_point now);
  ParticipantActions leave() const;

  // Set by the adapter from the runtime before each event: a critical section is open.
  void set_critical_section_open(bool open) { critical_section_open_ = open; }

  // -- what it knows -------------------------------------------------------------------
  ParticipantReport report(bool leaving = false) const;
  // The newest epoch applied, scheduled or refused: anything at or below it is stale.
  std::uint64_t newest_epoch() const;
  // A received state waits for a critical section to close.
  bool deferring() const { return pending_epoch_ > applied_epoch_; }
  bool in_critical_section() const { return critical_section_open_ || deferring(); }
  std::uint64_t applied_epoch() const { return applied_epoch_; }
  const std::string& node() const { return node_; }
  const std::vector<std::string>& hosted() const { return hosted_; }
  bool manager_lost() const { return manager_lost_; }
  // This node's heartbeat period: its own, or the longer one the manager asks for.
  Clock::duration status_period() const { return status_period_; }
  // When tick() has something to do next: a heartbeat, a repeat, or the manager-lost check.
  Clock::time_point next_tick() const;

 private:
  // Whether a report is repeated shortly after: never, if the link shows loss, always.
  enum class Repeat { no, if_lossy, always };
  PublishStatus send(Clock::time_point now, Repeat repeat = Repeat::no);
  ParticipantActions heard_manager(const std::string& manager_id,
                                   std::optional<Clock::time_point> now);

  std::string node_;
  std::string incarnation_;
  std::vector<LayerInfo> layers_;
  std::vector<std::string> hosted_;
  Clock::duration heartbeat_period_;
  Clock::duration status_period_;
  Clock::duration manager_timeout_;
  std::vector<Clock::duration> repeats_;
  std::vector<Clock::time_point> repeat_at_;
  std::optional<Clock::time_point> manager_heard_;
  std::optional<Clock::time_point> last_message_;  // the manager's last message, if any
  std::optional<Clock::time_point> loss_seen_;     // when it was last heard late
  bool manager_lost_ = false;
  std::string manager_id_;
  std::uint64_t applied_epoch_ = 0;
  std::string applied_manager_id_;
  std::vector<std::string> active_;
  std::uint64_t pending_epoch_ = 0;
  std::uint64_t failed_epoch_ = 0;
  std::string error_;
  bool critical_section_open_ = false;
  std::optional<Clock::time_point> last_sent_;
  std::uint64_t vote_epoch_ = 0;
  std::string vote_manager_id_;
  bool vote_yes_ = false;
  std::string vote_reason_;
  // The newest epoch voted on per manager (the last few, oldest first): a late copy of an
  // older proposal is over, not voted on (nor its vetoes asked) again.
  std::vector<std::pair<std::string, std::uint64_t>> voted_;
};

}  // namespace contextros::ros
