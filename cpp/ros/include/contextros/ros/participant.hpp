// C++ context nodes: rcl nodes whose layered functions follow the Layer manager.
//
// A Participant speaks docs/protocol.md for the process on one rcl node, exactly as the
// Python ContextParticipant does: it announces the layers with their relations, applies
// every newer state with contextros::set_active on its own thread, acknowledges after
// applying, reports a switch deferred by a CriticalSection as pending, refuses a state
// the runtime cannot apply (failed_epoch + error), heartbeats, and says it leaves.
//
// The decisive configuration is per process, so a process needs one participant: a
// ContextNode joins the process's shared participant (the first one carries it, the others
// are announced as hosted nodes; when the carrier goes, the next one takes over).
//
// Works with any rcl_node_t: a plain rcl program's, or an rclcpp node's
// (`*node->get_node_base_interface()->get_rcl_node_handle()`, see contextros/ros/rclcpp.hpp).
// The rcl node must outlive the Participant / ContextNode attached to it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "contextros/ros/participant_protocol.hpp"

struct rcl_node_s;

namespace contextros::ros {

struct ParticipantOptions {
  // The layers this node implements, announced with their relations as defined in the
  // process when the participant starts; nullopt: every layer defined in the process.
  std::optional<std::vector<std::string>> layers;
  Clock::duration heartbeat_period = default_heartbeat_period;
  // Not hearing the manager (state or heartbeat) this long, the node is cut off: it keeps
  // its layers, reports manager_lost and tells the manager listeners.
  Clock::duration manager_timeout = default_manager_timeout;
};

// Called on the participant's thread after each state the process applied.
using StateListener = std::function<void(const LayerState&)>;
// Called on the participant's thread with true when the manager is lost (not heard for
// manager_timeout), with false when it is heard again. A listener may set_active a safe
// configuration; once the manager is heard again, the participant re-applies the state it
// applied last (if the runtime's layers differ from it) or the manager's newer state.
using ManagerListener = std::function<void(bool lost)>;
// Asked about an atomic activation's proposed state, once per proposal, on a worker thread
// of the participant (one proposal at a time; heartbeats go on meanwhile): return why this
// process cannot apply it ("" : it can). Destroying the participant waits up to 5 s for a
// veto still running. Besides, the participant votes no while a
// critical section is open and when the proposal breaks a relation it declares.
using Veto = std::function<std::string(const LayerState&)>;

// Raised when a participant cannot be set up (an rcl call failed), with rcl's message.
class ParticipantError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Participant {
 public:
  // Attaches to `node` (not owned), announces itself and starts following the manager on
  // a thread of its own.
  explicit Participant(rcl_node_s& node, ParticipantOptions options = {});
  // The same, carrying on for the process from the participant it replaces (a snapshot of
  // its protocol): its epoch and layers, so an older state cannot take the process back.
  Participant(rcl_node_s& node, ParticipantOptions options, const ParticipantProtocol& previous);
  // Says it leaves (the manager drops it at once) and stops its thread. Destroyed on its own
  // thread (by a listener or veto), it cannot join that thread: the thread stops as soon as
  // the listener returns and frees the rest then (the rcl node must outlive that too).
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  // Speak for another node of this process too (its layers join the announced ones).
  void host(const std::string& node_name, std::optional<std::vector<std::string>> layers);
  // Stop speaking for it.
  void release(const std::string& node_name);
  void add_listener(StateListener listener);
  void add_manager_listener(ManagerListener listener);
  void add_veto(Veto veto);

  const std::string& node_name() const;
  std::uint64_t applied_epoch() const;
  // A copy of where its protocol stands (for a successor).
  ParticipantProtocol protocol() const;

 private:
  Participant(rcl_node_s& node, ParticipantOptions options, const ParticipantProtocol* previous);

  struct Impl;
  std::shared_ptr<Impl> impl_;  // shared with its thread
};

// A node of this process that follows the manager through the process's shared participant.
// Destroy it before its rcl node.
class ContextNode {
 public:
  explicit ContextNode(rcl_node_s& node, ParticipantOptions options = {});
  ~ContextNode();
  ContextNode(const ContextNode&) = delete;
  ContextNode& operator=(const ContextNode&) = delete;

  // Listeners belong to the process's participant and survive a hand-over.
  static void add_listener(StateListener listener);
  static void add_manager_listener(ManagerListener listener);
  static void add_veto(Veto veto);
  // The fully qualified name of the node carrying the process's participant ("" if none).
  static std::string carrier();

 private:
  rcl_node_s* node_;
};

}  // namespace contextros::ros
