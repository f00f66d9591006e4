// The participant's inside (internal): the protocol adapter (participant_adapter.cpp) and
// its thread's wait loop (wait_loop.cpp), sharing one Impl that the Participant handle
// (participant.cpp) holds.
#pragma once

#include <rcl/rcl.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <contextros/activation.hpp>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "contextros/ros/participant.hpp"
#include "contextros/ros/rcl_handles.hpp"

namespace contextros::ros {

// Switches the runtime settled, handed to the participant's thread from whichever thread
// settled them (the one that closed a critical section).
class Inbox {
 public:
  using Settled = std::pair<LayerState, SwitchOutcome>;
  using Answer = std::pair<LayerState, std::string>;  // a proposal and its vetoes' reasons
  explicit Inbox(RclGuardCondition& wake) : wake_(&wake) {}
  void post(const LayerState& state, const SwitchOutcome& outcome) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (wake_ != nullptr) {
      settled_.emplace_back(state, outcome);
      wake_->trigger();
    }
  }
  std::vector<Settled> take() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::exchange(settled_, {});
  }
  // The vetoes' answer about a proposal, from their worker thread.
  void post_answer(const LayerState& proposal, std::string reasons) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (wake_ != nullptr) {
      answers_.emplace_back(proposal, std::move(reasons));
      wake_->trigger();
    }
  }
  std::vector<Answer> take_answers() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::exchange(answers_, {});
  }
  void close() {
    std::lock_guard<std::mutex> lock(mutex_);
    wake_ = nullptr;
  }

 private:
  std::mutex mutex_;
  RclGuardCondition* wake_;  // not owned; null once the participant is gone
  std::vector<Settled> settled_;
  std::vector<Answer> answers_;
};

// Runs the vetoes off the participant's thread, one proposal at a time, so heartbeats go
// on meanwhile. A newer proposal replaces one still waiting its turn. Destroyed, it waits
// for a veto still thinking (up to `patience`), so that no user code outlives the
// participant; past that, the thread is left to finish on its own and said so.
class VetoWorker {
 public:
  using Job = std::function<void()>;
  explicit VetoWorker(std::chrono::milliseconds patience)
      : patience_(patience), shared_(std::make_shared<Shared>()) {}
  ~VetoWorker();
  VetoWorker(const VetoWorker&) = delete;
  VetoWorker& operator=(const VetoWorker&) = delete;
  void ask(Job job);

 private:
  // What the thread uses: shared, so that a thread left to finish never reaches freed memory.
  struct Shared {
    std::mutex mutex;
    std::condition_variable changed;
    std::optional<Job> next;
    bool busy = false;
    bool stopping = false;
  };
  static void run(const std::shared_ptr<Shared>& shared);
  std::chrono::milliseconds patience_;
  std::shared_ptr<Shared> shared_;
  std::thread thread_;  // started by the first job
};

struct Participant::Impl {
  Impl(rcl_node_t& node, const ParticipantOptions& options);
  ~Impl();

  // -- the protocol adapter (participant_adapter.cpp) --

  // Runs the protocol's actions; called with `mutex` held. States to apply are queued for
  // event(), which applies them without the lock (the runtime runs observers meanwhile).
  void run(const ParticipantActions& actions);

  // On the participant's thread (or in the constructor): the only caller that applies.
  void event(const std::function<ParticipantActions()>& happen);

  // Called without `mutex`. A switch the runtime settles at once is recorded at once (the
  // next state taken in this wake-up is compared with it); a deferred one goes through the
  // inbox.
  void apply(const LayerState& state);

  // Called with `mutex` held: reports a settled switch; an applied one is told to the
  // listeners (later, without the lock).
  void settle(const LayerState& state, const SwitchOutcome& outcome);

  // Reports the deferred switches the runtime settled since the last call; returns the
  // states applied since the last call (deferred or not), for the listeners.
  std::vector<LayerState> settle_deferred();

  void take_states(RclSubscription& subscription);

  void take_proposals();
  // Votes on the proposals whose vetoes answered (in their worker thread) meanwhile.
  void take_veto_answers();

  // Called with `mutex` held; at most one line per 10 s (anyone can publish a state).
  void log_rejected(const StateRejected& rejected);

  void notify_manager_changes();

  void notify(const std::vector<LayerState>& applied);

  // Called with `mutex` held.
  void announce_hosting();

  // -- the participant's thread (wait_loop.cpp) --

  void loop();

  // One wake-up of the participant's thread; false once it is stopping.
  bool turn();

  // -- state --

  rcl_node_t& node;
  const char* logger = rcl_node_get_logger_name(&node);
  std::vector<LayerInfo> own_layers;
  std::vector<std::pair<std::string, std::vector<LayerInfo>>> hosted;  // in joining order
  std::mutex mutex;  // protocol, hosted, publishing
  ParticipantProtocol protocol;
  RclPublisher status_publisher;
  RclSubscription state_subscription;
  RclSubscription heartbeat_subscription;
  RclSubscription proposal_subscription;
  RclGuardCondition wake;
  RclWaitSet wait_set;
  std::shared_ptr<Inbox> inbox;
  std::mutex listeners_mutex;
  std::vector<StateListener> listeners;
  std::vector<ManagerListener> manager_listeners;
  std::vector<Veto> vetoes;
  std::vector<bool> manager_changes;  // lost (true) / found (false), to tell the listeners
  std::vector<LayerState> applied_states;  // to tell the listeners
  std::vector<LayerState> to_apply;        // by event(), once `mutex` is released
  bool restore_applied = false;            // the manager was found again
  bool never_joined = false;               // lost before any manager's state: the log's words
  // The proposal (epoch, manager) whose vetoes think in their worker thread, if any.
  std::optional<std::pair<std::uint64_t, std::string>> asking;
  std::optional<Clock::time_point> last_rejection_logged;
  std::atomic<bool> stopping{false};
  std::thread thread;
  // Last: destroyed first, while everything a veto's answer reaches is still there.
  VetoWorker veto_worker{std::chrono::seconds(5)};
};

// The declarations of `names` as defined in this process (by default every defined layer).
std::vector<LayerInfo> declarations_of(const std::optional<std::vector<std::string>>& names);

}  // namespace contextros::ros
