// The protocol adapter: runs ParticipantProtocol's actions on rcl (publishes reports,
// applies states through the runtime, tells listeners, asks vetoes) and feeds it what
// arrives; the wait loop (wait_loop.cpp) calls it.
#include <rcutils/logging_macros.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <random>

#include "contextros/ros/topics.hpp"
#include "messages.hpp"
#include "participant_impl.hpp"

namespace contextros::ros {

namespace msg = contextros_interfaces::msg;

namespace {

std::string new_incarnation() {
  std::random_device random;
  char suffix[9];
  std::snprintf(suffix, sizeof suffix, "%08x", static_cast<unsigned>(random()));
  return std::to_string(::getpid()) + "-" + suffix;
}

}  // namespace

std::vector<LayerInfo> declarations_of(const std::optional<std::vector<std::string>>& names) {
  std::vector<LayerInfo> defined = defined_layers();
  if (!names) {
    return defined;
  }
  std::vector<LayerInfo> chosen;
  for (const std::string& name : *names) {
    auto found = std::find_if(defined.begin(), defined.end(),
                              [&](const LayerInfo& layer) { return layer.name == name; });
    if (found == defined.end()) {
      throw ParticipantError("layer '" + name +
                             "' is not defined in this process: link its layer file, or "
                             "leave it out of ParticipantOptions::layers");
    }
    chosen.push_back(*found);
  }
  return chosen;
}

Participant::Impl::Impl(rcl_node_t& node, const ParticipantOptions& options)
    : node(node),
      own_layers(declarations_of(options.layers)),
      protocol(rcl_node_get_fully_qualified_name(&node), new_incarnation(), own_layers,
               options.heartbeat_period, options.manager_timeout),
      status_publisher(node, type_support<msg::ParticipantStatus>(), status_topic, status_qos()),
      state_subscription(node, type_support<msg::LayerState>(), state_topic, state_qos()),
      heartbeat_subscription(node, type_support<msg::LayerState>(), heartbeat_topic,
                             heartbeat_qos()),
      proposal_subscription(node, type_support<msg::LayerState>(), proposal_topic,
                            proposal_qos()),
      wake(node.context),
      wait_set(node.context, 3, 1),
      inbox(std::make_shared<Inbox>(wake)) {}

Participant::Impl::~Impl() { inbox->close(); }

// Runs the protocol's actions; called with `mutex` held. States to apply are queued for
// event(), which applies them without the lock (the runtime runs observers meanwhile).
void Participant::Impl::run(const ParticipantActions& actions) {
  for (const ParticipantAction& action : actions) {
    if (const auto* apply = std::get_if<ApplyState>(&action)) {
      to_apply.push_back(apply->state);
    } else if (const auto* publish = std::get_if<PublishStatus>(&action)) {
      // A failure is repeated by the next heartbeat.
      status_publisher.publish(report_to_msg(publish->report));
    } else if (const auto* rejected = std::get_if<StateRejected>(&action)) {
      log_rejected(*rejected);
    } else if (const auto* lost = std::get_if<ManagerLost>(&action)) {
      const double seconds = std::chrono::duration<double>(lost->silent_for).count();
      std::string active;
      for (const std::string& layer : protocol.report().active) {
        active += (active.empty() ? "" : ", ") + layer;
      }
      // Never joined one yet (a node started before its manager): not "lost", not "again".
      never_joined = protocol.report().applied_manager_id.empty();
      RCUTILS_LOG_WARN_NAMED(logger, "no Layer manager heard %s %.1f s: keeping layers [%s] "
                             "(epoch %llu)", never_joined ? "in the first" : "for", seconds,
                             active.c_str(),
                             static_cast<unsigned long long>(protocol.applied_epoch()));
      manager_changes.push_back(true);
    } else if (const auto* found = std::get_if<ManagerFound>(&action)) {
      const std::string who = found->manager_id.empty() ? "" : " " + found->manager_id;
      RCUTILS_LOG_INFO_NAMED(logger, "Layer manager%s heard%s", who.c_str(),
                             never_joined ? " for the first time" : " again");
      manager_changes.push_back(false);
      restore_applied = true;
    }
  }
}

// On the participant's thread (or in the constructor): the only caller that applies.
void Participant::Impl::event(const std::function<ParticipantActions()>& happen) {
  std::vector<LayerState> states;
  std::optional<LayerState> applied_state;
  {
    std::lock_guard<std::mutex> lock(mutex);
    protocol.set_critical_section_open(in_critical_section());
    run(happen());
    states.swap(to_apply);
    // The manager is back: a configuration set while it was lost (a safe fallback) gives
    // way to the state applied last, unless a newer one comes now. Its epoch is not
    // newer, so the manager's heartbeat alone would never replace it.
    if (std::exchange(restore_applied, false) && states.empty() &&
        protocol.applied_epoch() > 0) {
      ParticipantReport report = protocol.report();
      applied_state = LayerState{report.applied_epoch, std::move(report.active), "", "",
                                 std::move(report.applied_manager_id)};
    }
  }
  for (const LayerState& state : states) {
    apply(state);
  }
  if (applied_state && active_layers() != applied_state->active) {
    RCUTILS_LOG_INFO_NAMED(logger, "back to the layers of epoch %llu",
                           static_cast<unsigned long long>(applied_state->epoch));
    apply(*applied_state);  // acknowledged already: the protocol ignores its outcome
  }
}

// Called without `mutex`. A switch the runtime settles at once is recorded at once (the
// next state taken in this wake-up is compared with it); a deferred one goes through the
// inbox.
void Participant::Impl::apply(const LayerState& state) {
  // A deferred switch may settle after this participant is gone: the callback holds the
  // inbox, not the participant. Called on this thread during set_active, the callback
  // is the synchronous one: its outcome is the one returned.
  std::shared_ptr<Inbox> box = inbox;
  auto in_call = std::make_shared<std::atomic<bool>>(true);
  const std::thread::id caller = std::this_thread::get_id();
  SwitchOutcome outcome{SwitchStatus::failed, 0, ""};
  try {
    outcome = set_active(state.active, [box, state, in_call, caller](const SwitchOutcome& done) {
      if (in_call->load() && std::this_thread::get_id() == caller) return;
      box->post(state, done);  // on the thread closing the critical section
    });
  } catch (const std::exception& error) {
    outcome.error = error.what();
  } catch (...) {
    outcome.error = "the switch threw";
  }
  in_call->store(false);
  std::lock_guard<std::mutex> lock(mutex);
  protocol.set_critical_section_open(in_critical_section());
  if (outcome.status == SwitchStatus::deferred) {
    run(protocol.deferred(state, Clock::now()));
  } else {
    settle(state, outcome);
  }
}

// Called with `mutex` held: reports a settled switch; an applied one is told to the
// listeners (later, without the lock).
void Participant::Impl::settle(const LayerState& state, const SwitchOutcome& outcome) {
  if (outcome.status == SwitchStatus::applied) {
    if (state.epoch > protocol.applied_epoch()) {
      applied_states.push_back(state);
    }
    run(protocol.applied(state, Clock::now()));
  } else {
    const std::string why = outcome.error.empty() ? "the switch was dropped" : outcome.error;
    if (state.epoch > protocol.applied_epoch()) {  // else moot, as protocol.failed() says
      RCUTILS_LOG_ERROR_NAMED(logger, "cannot apply epoch %llu: %s",
                              static_cast<unsigned long long>(state.epoch), why.c_str());
    }
    run(protocol.failed(state, why, Clock::now()));
  }
}

// Reports the deferred switches the runtime settled since the last call; returns the
// states applied since the last call (deferred or not), for the listeners.
std::vector<LayerState> Participant::Impl::settle_deferred() {
  for (const auto& [state, outcome] : inbox->take()) {
    event([&] {
      settle(state, outcome);
      return ParticipantActions{};
    });
  }
  std::lock_guard<std::mutex> lock(mutex);
  return std::exchange(applied_states, {});
}

void Participant::Impl::take_states(RclSubscription& subscription) {
  msg::LayerState message;
  while (subscription.take(message)) {
    const LayerState state = state_from_msg(message);
    event([&] { return protocol.receive_state(state, Clock::now()); });
  }
}

namespace {

// What the vetoes say about `proposal` ("" if none objects); on their worker thread.
std::string ask_vetoes(const std::vector<Veto>& vetoes, const LayerState& proposal) {
  std::string reasons;
  for (const Veto& veto : vetoes) {
    std::string reason;
    try {
      reason = veto(proposal);
    } catch (const std::exception& error) {  // a veto that fails says no, and is logged
      reason = std::string("a veto failed: ") + error.what();
      RCUTILS_LOG_ERROR_NAMED("contextros", "%s (epoch %llu: voting no)", reason.c_str(),
                              static_cast<unsigned long long>(proposal.epoch));
    } catch (...) {
      reason = "a veto failed";
      RCUTILS_LOG_ERROR_NAMED("contextros", "a veto failed (epoch %llu: voting no)",
                              static_cast<unsigned long long>(proposal.epoch));
    }
    if (!reason.empty()) reasons += (reasons.empty() ? "" : "; ") + reason;
  }
  return reasons;
}

}  // namespace

// A proposal (repeated every 50 ms while the vote is open): without vetoes the node votes
// at once; with vetoes they are asked once, in a worker thread (heartbeats go on), and the
// vote follows their answer (take_veto_answers).
void Participant::Impl::take_proposals() {
  msg::LayerState message;
  while (proposal_subscription.take(message)) {
    const LayerState proposal = state_from_msg(message);
    bool wanted = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      wanted = protocol.wants_vote(proposal);
    }
    std::vector<Veto> to_ask;
    if (wanted) {
      std::lock_guard<std::mutex> lock(listeners_mutex);
      to_ask = vetoes;
    }
    if (to_ask.empty()) {
      event([&] { return protocol.receive_proposal(proposal, Clock::now()); });
      continue;
    }
    event([&] { return protocol.receive_proposal(proposal, Clock::now(), {}, false); });
    auto key = std::make_pair(proposal.epoch, proposal.manager_id);
    if (asking == key) {
      continue;  // its vetoes are still thinking
    }
    asking = std::move(key);
    // The job holds the inbox, not the participant.
    veto_worker.ask([box = inbox, proposal, to_ask = std::move(to_ask)] {
      box->post_answer(proposal, ask_vetoes(to_ask, proposal));
    });
  }
}

VetoWorker::~VetoWorker() {
  std::unique_lock<std::mutex> lock(shared_->mutex);
  shared_->stopping = true;
  shared_->next.reset();
  shared_->changed.notify_all();
  if (!thread_.joinable()) return;
  // Destroyed by a veto (on the worker itself), it cannot wait for it.
  const bool finished = thread_.get_id() != std::this_thread::get_id() &&
                        shared_->changed.wait_for(lock, patience_,
                                                  [this] { return !shared_->busy; });
  lock.unlock();
  if (finished) {
    thread_.join();
    return;
  }
  if (thread_.get_id() != std::this_thread::get_id()) {
    RCUTILS_LOG_WARN_NAMED("contextros",
                           "a veto still runs %.1f s after its participant was destroyed: "
                           "left to finish on its own",
                           std::chrono::duration<double>(patience_).count());
  }
  thread_.detach();
}

void VetoWorker::ask(Job job) {
  std::lock_guard<std::mutex> lock(shared_->mutex);
  if (shared_->stopping) return;
  shared_->next = std::move(job);
  if (!thread_.joinable()) {
    thread_ = std::thread(run, shared_);
  }
  shared_->changed.notify_all();
}

void VetoWorker::run(const std::shared_ptr<Shared>& shared) {
  std::unique_lock<std::mutex> lock(shared->mutex);
  while (true) {
    shared->changed.wait(lock, [&] { return shared->stopping || shared->next.has_value(); });
    if (shared->stopping) return;
    Job job = std::move(*shared->next);
    shared->next.reset();
    shared->busy = true;
    lock.unlock();
    job();  // ask_vetoes catches what a veto throws
    lock.lock();
    shared->busy = false;
    shared->changed.notify_all();
  }
}

void Participant::Impl::take_veto_answers() {
  for (const auto& [proposal, reasons] : inbox->take_answers()) {
    if (!asking || *asking != std::make_pair(proposal.epoch, proposal.manager_id)) {
      continue;  // a newer proposal came meanwhile: this one is over
    }
    asking.reset();
    event([&] { return protocol.receive_proposal(proposal, Clock::now(), reasons); });
  }
}

// Called with `mutex` held; at most one line per 10 s (anyone can publish a state).
void Participant::Impl::log_rejected(const StateRejected& rejected) {
  const Clock::time_point now = Clock::now();
  if (last_rejection_logged && now - *last_rejection_logged < std::chrono::seconds(10)) {
    return;
  }
  last_rejection_logged = now;
  std::string problems;
  for (const std::string& problem : rejected.problems) {
    problems += (problems.empty() ? "" : "; ") + problem;
  }
  RCUTILS_LOG_WARN_NAMED(logger, "ignored a layer state: %s", problems.c_str());
}

void Participant::Impl::notify_manager_changes() {
  std::vector<bool> changes;
  {
    std::lock_guard<std::mutex> lock(mutex);
    changes.swap(manager_changes);
  }
  if (changes.empty()) {
    return;
  }
  std::vector<ManagerListener> to_call;
  {
    std::lock_guard<std::mutex> lock(listeners_mutex);
    to_call = manager_listeners;
  }
  for (bool lost : changes) {
    for (const ManagerListener& listener : to_call) {
      if (stopping.load()) return;
      try {
        listener(lost);
      } catch (const std::exception& error) {  // a listener must not stop the node
        RCUTILS_LOG_ERROR_NAMED(logger, "a manager listener failed: %s", error.what());
      } catch (...) {
        RCUTILS_LOG_ERROR_NAMED(logger, "a manager listener failed");
      }
    }
  }
}

void Participant::Impl::notify(const std::vector<LayerState>& applied) {
  std::vector<StateListener> to_call;
  {
    std::lock_guard<std::mutex> lock(listeners_mutex);
    to_call = listeners;
  }
  for (const LayerState& state : applied) {
    for (const StateListener& listener : to_call) {
      if (stopping.load()) return;  // a listener destroyed the participant
      try {
        listener(state);
      } catch (const std::exception& error) {  // a listener must not stop the node
        RCUTILS_LOG_ERROR_NAMED(logger, "a state listener failed: %s", error.what());
      } catch (...) {
        RCUTILS_LOG_ERROR_NAMED(logger, "a state listener failed");
      }
    }
  }
}

// Called with `mutex` held.
void Participant::Impl::announce_hosting() {
  std::vector<LayerInfo> layers = own_layers;
  std::vector<std::string> names;
  for (const auto& [name, declarations] : hosted) {
    names.push_back(name);
    for (const LayerInfo& layer : declarations) {
      auto known = std::find_if(layers.begin(), layers.end(),
                                [&](const LayerInfo& l) { return l.name == layer.name; });
      if (known == layers.end()) {
        layers.push_back(layer);
      }
    }
  }
  std::sort(names.begin(), names.end());
  protocol.set_critical_section_open(in_critical_section());
  run(protocol.host(std::move(names), std::move(layers), Clock::now()));
}

}  // namespace contextros::ros
