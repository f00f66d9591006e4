// The rcl adapter around ParticipantProtocol: translates messages, runs the participant's
// thread (one wait set: the state subscription and a guard condition), calls the runtime.
#include "contextros/ros/participant.hpp"

#include <rcl/rcl.h>
#include <rcutils/logging_macros.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <contextros/activation.hpp>
#include <contextros_interfaces/msg/layer_state.hpp>
#include <contextros_interfaces/msg/participant_status.hpp>
#include <cstdio>
#include <mutex>
#include <random>
#include <thread>
#include <utility>

#include "contextros/ros/topics.hpp"
#include "contextros/ros/rcl_handles.hpp"
#include "rosidl_typesupport_cpp/message_type_support.hpp"

namespace contextros::ros {

namespace msg = contextros_interfaces::msg;

// -- QoS (docs/protocol.md) ---------------------------------------------------------------

namespace {

rmw_qos_profile_t keep_last(std::size_t depth, rmw_qos_reliability_policy_t reliability,
                            rmw_qos_durability_policy_t durability) {
  rmw_qos_profile_t qos = rmw_qos_profile_default;
  qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
  qos.depth = depth;
  qos.reliability = reliability;
  qos.durability = durability;
  return qos;
}

}  // namespace

rmw_qos_profile_t state_qos() {
  return keep_last(1, RMW_QOS_POLICY_RELIABILITY_RELIABLE,
                   RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL);
}

rmw_qos_profile_t heartbeat_qos() {
  return keep_last(1, RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT, RMW_QOS_POLICY_DURABILITY_VOLATILE);
}

rmw_qos_profile_t proposal_qos() { return heartbeat_qos(); }

rmw_qos_profile_t status_qos() {
  return keep_last(100, RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT,
                   RMW_QOS_POLICY_DURABILITY_VOLATILE);
}

namespace {

// -- messages <-> protocol values (the twin of src/contextros/ros/messages.py) -----------

std::vector<std::string> sorted(std::vector<std::string> names) {
  std::sort(names.begin(), names.end());
  return names;
}

msg::LayerInfo layer_to_msg(const LayerInfo& layer) {
  msg::LayerInfo info;
  info.name = layer.name;
  info.excludes = sorted(layer.excludes);
  info.required = sorted(layer.required);
  info.after = sorted(layer.after);
  info.group = layer.group;
  return info;
}

LayerState state_from_msg(const msg::LayerState& state) {
  return LayerState{state.epoch,      state.active_layers, state.requester, state.reason,
                    state.manager_id, state.stamp.sec + state.stamp.nanosec * 1e-9};
}

msg::ParticipantStatus report_to_msg(const ParticipantReport& report) {
  msg::ParticipantStatus status;
  status.node = report.node;
  status.incarnation = report.incarnation;
  for (const LayerInfo& layer : report.layers) {
    status.layers.push_back(layer_to_msg(layer));
  }
  status.applied_epoch = report.applied_epoch;
  status.applied_manager_id = report.applied_manager_id;
  status.active_layers = report.active;
  status.in_critical_section = report.in_critical_section;
  status.pending_epoch = report.pending_epoch;
  status.failed_epoch = report.failed_epoch;
  status.error = report.error;
  status.leaving = report.leaving;
  const auto since_epoch = std::chrono::system_clock::now().time_since_epoch();
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
  status.stamp.sec = static_cast<std::int32_t>(seconds.count());
  status.stamp.nanosec = static_cast<std::uint32_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(since_epoch - seconds).count());
  status.hosted_nodes = report.hosted;
  status.manager_lost = report.manager_lost;
  status.vote_epoch = report.vote_epoch;
  status.vote_manager_id = report.vote_manager_id;
  status.vote_yes = report.vote_yes;
  status.vote_reason = report.vote_reason;
  status.language = "C++";
  return status;
}

std::string new_incarnation() {
  std::random_device random;
  char suffix[9];
  std::snprintf(suffix, sizeof suffix, "%08x", static_cast<unsigned>(random()));
  return std::to_string(::getpid()) + "-" + suffix;
}

// The declarations of `names` as defined in this process (by default every defined layer).
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

}  // namespace

// -- the participant ------------------------------------------------------------------------

// Switches the runtime settled, handed to the participant's thread from whichever thread
// settled them (the one that closed a critical section).
class Inbox {
 public:
  using Settled = std::pair<LayerState, SwitchOutcome>;
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
  void close() {
    std::lock_guard<std::mutex> lock(mutex_);
    wake_ = nullptr;
  }

 private:
  std::mutex mutex_;
  RclGuardCondition* wake_;  // not owned; null once the participant is gone
  std::vector<Settled> settled_;
};

struct Participant::Impl {
  Impl(rcl_node_t& node, const ParticipantOptions& options)
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

  ~Impl() { inbox->close(); }

  // Runs the protocol's actions; called with `mutex` held. States to apply are queued for
  // event(), which applies them without the lock (the runtime runs observers meanwhile).
  void run(const ParticipantActions& actions) {
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
        RCUTILS_LOG_WARN_NAMED(logger, "no Layer manager heard for %.1f s: keeping layers [%s] "
                               "(epoch %llu)", seconds, active.c_str(),
                               static_cast<unsigned long long>(protocol.applied_epoch()));
        manager_changes.push_back(true);
      } else if (const auto* found = std::get_if<ManagerFound>(&action)) {
        RCUTILS_LOG_INFO_NAMED(logger, "Layer manager %s heard again", found->manager_id.c_str());
        manager_changes.push_back(false);
        restore_applied = true;
      }
    }
  }

  // On the participant's thread (or in the constructor): the only caller that applies.
  void event(const std::function<ParticipantActions()>& happen) {
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
  void apply(const LayerState& state) {
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
  void settle(const LayerState& state, const SwitchOutcome& outcome) {
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
  std::vector<LayerState> settle_deferred() {
    for (const auto& [state, outcome] : inbox->take()) {
      event([&] {
        settle(state, outcome);
        return ParticipantActions{};
      });
    }
    std::lock_guard<std::mutex> lock(mutex);
    return std::exchange(applied_states, {});
  }

  void take_states(RclSubscription& subscription) {
    msg::LayerState message;
    while (subscription.take(message)) {
      const LayerState state = state_from_msg(message);
      event([&] { return protocol.receive_state(state, Clock::now()); });
    }
  }

  void take_proposals() {
    msg::LayerState message;
    while (proposal_subscription.take(message)) {
      const LayerState proposal = state_from_msg(message);
      bool wanted = false;
      {
        std::lock_guard<std::mutex> lock(mutex);
        wanted = protocol.wants_vote(proposal);
      }
      std::vector<Veto> to_ask;
      if (wanted) {  // once per proposal, not on each of its repeats
        std::lock_guard<std::mutex> lock(listeners_mutex);
        to_ask = vetoes;
      }
      std::string reasons;
      for (const Veto& veto : to_ask) {
        std::string reason;
        try {
          reason = veto(proposal);
        } catch (const std::exception& error) {  // a veto that fails says no
          reason = std::string("a veto failed: ") + error.what();
        } catch (...) {
          reason = "a veto failed";
        }
        if (!reason.empty()) reasons += (reasons.empty() ? "" : "; ") + reason;
      }
      event([&] { return protocol.receive_proposal(proposal, Clock::now(), reasons); });
    }
  }

  // Called with `mutex` held; at most one line per 10 s (anyone can publish a state).
  void log_rejected(const StateRejected& rejected) {
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

  void notify_manager_changes() {
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

  void notify(const std::vector<LayerState>& applied) {
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

  void loop() {
    while (!stopping.load()) {
      try {
        if (!turn()) break;
      } catch (const std::exception& error) {  // nothing may end the thread but stopping
        RCUTILS_LOG_ERROR_NAMED(logger, "participant: %s", error.what());
      } catch (...) {
        RCUTILS_LOG_ERROR_NAMED(logger, "participant: an unknown exception");
      }
    }
  }

  // One wake-up of the participant's thread; false once it is stopping.
  bool turn() {
    auto timeout = std::chrono::nanoseconds(0);
    {
      std::lock_guard<std::mutex> lock(mutex);
      timeout = std::max(std::chrono::nanoseconds(0),
                         std::chrono::duration_cast<std::chrono::nanoseconds>(
                             protocol.next_tick() - Clock::now()));
    }
    rcl_wait_set_t* set = wait_set.get();
    if (rcl_wait_set_clear(set) != RCL_RET_OK ||
        rcl_wait_set_add_subscription(set, state_subscription.get(), nullptr) != RCL_RET_OK ||
        rcl_wait_set_add_subscription(set, heartbeat_subscription.get(), nullptr) != RCL_RET_OK ||
        rcl_wait_set_add_subscription(set, proposal_subscription.get(), nullptr) != RCL_RET_OK ||
        rcl_wait_set_add_guard_condition(set, wake.get(), nullptr) != RCL_RET_OK) {
      std::fprintf(stderr, "contextros: participant wait set: %s\n", rcl_get_error_string().str);
      rcl_reset_error();
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      return true;
    }
    const rcl_ret_t waited = rcl_wait(set, timeout.count());
    if (waited != RCL_RET_OK && waited != RCL_RET_TIMEOUT) {
      rcl_reset_error();  // the context is shutting down; the destructor stops us
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      return true;
    }
    if (stopping.load()) {
      return false;
    }
    if (set->subscriptions[0] != nullptr) {
      take_states(state_subscription);
    }
    if (set->subscriptions[1] != nullptr) {
      take_states(heartbeat_subscription);
    }
    if (set->subscriptions[2] != nullptr) {
      take_proposals();
    }
    notify(settle_deferred());
    if (stopping.load()) {
      return false;
    }
    event([&] { return protocol.tick(Clock::now()); });
    notify_manager_changes();
    return true;
  }

  // Called with `mutex` held.
  void announce_hosting() {
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
  std::optional<Clock::time_point> last_rejection_logged;
  std::atomic<bool> stopping{false};
  std::thread thread;
};

Participant::Participant(rcl_node_t& node, ParticipantOptions options)
    : Participant(node, std::move(options), nullptr) {}

Participant::Participant(rcl_node_t& node, ParticipantOptions options,
                         const ParticipantProtocol& previous)
    : Participant(node, std::move(options), &previous) {}

Participant::Participant(rcl_node_t& node, ParticipantOptions options,
                         const ParticipantProtocol* previous)
    : impl_(std::make_shared<Impl>(node, options)) {
  if (previous != nullptr) {
    impl_->protocol.continue_from(*previous);
  }
  impl_->event([this] { return impl_->protocol.announce(Clock::now()); });
  // The thread shares the Impl: destroyed from the thread itself, it outlives ~Participant.
  impl_->thread = std::thread([impl = impl_] { impl->loop(); });
}

Participant::~Participant() {
  impl_->stopping.store(true);
  impl_->wake.trigger();
  const bool own_thread = std::this_thread::get_id() == impl_->thread.get_id();
  if (own_thread) {
    // From a listener: the loop stops when it returns and frees the Impl then.
    impl_->thread.detach();
  } else {
    impl_->thread.join();
  }
  try {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->run(impl_->protocol.leave());
    std::this_thread::sleep_for(leave_repeat_after);
    impl_->run(impl_->protocol.leave());
  } catch (...) {  // best effort: the manager drops a silent node anyway
  }
}

void Participant::host(const std::string& node_name,
                       std::optional<std::vector<std::string>> layers) {
  std::vector<LayerInfo> declarations = declarations_of(layers);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto& hosted = impl_->hosted;
  auto known = std::find_if(hosted.begin(), hosted.end(),
                            [&](const auto& entry) { return entry.first == node_name; });
  if (known != hosted.end()) {
    known->second = std::move(declarations);
  } else {
    hosted.emplace_back(node_name, std::move(declarations));
  }
  impl_->announce_hosting();
}

void Participant::release(const std::string& node_name) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  auto& hosted = impl_->hosted;
  auto known = std::find_if(hosted.begin(), hosted.end(),
                            [&](const auto& entry) { return entry.first == node_name; });
  if (known != hosted.end()) {
    hosted.erase(known);
    impl_->announce_hosting();
  }
}

void Participant::add_listener(StateListener listener) {
  std::lock_guard<std::mutex> lock(impl_->listeners_mutex);
  impl_->listeners.push_back(std::move(listener));
}

void Participant::add_veto(Veto veto) {
  std::lock_guard<std::mutex> lock(impl_->listeners_mutex);
  impl_->vetoes.push_back(std::move(veto));
}

void Participant::add_manager_listener(ManagerListener listener) {
  std::lock_guard<std::mutex> lock(impl_->listeners_mutex);
  impl_->manager_listeners.push_back(std::move(listener));
}

const std::string& Participant::node_name() const { return impl_->protocol.node(); }

std::uint64_t Participant::applied_epoch() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->protocol.applied_epoch();
}

ParticipantProtocol Participant::protocol() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->protocol;
}

// -- one participant per process ----------------------------------------------------------

namespace {

struct Member {
  rcl_node_t* node;
  std::string name;
  ParticipantOptions options;
};

struct SharedParticipant {
  std::mutex mutex;
  std::vector<Member> members;  // in joining order; members[0] carries the participant
  std::unique_ptr<Participant> participant;
  std::vector<StateListener> listeners;
  std::vector<ManagerListener> manager_listeners;
  std::vector<Veto> vetoes;

  // `previous`: the protocol of the participant this one replaces, if any.
  void carry_by_first(const ParticipantProtocol* previous = nullptr) {
    const Member& carrier = members.front();
    participant = previous != nullptr
                      ? std::make_unique<Participant>(*carrier.node, carrier.options, *previous)
                      : std::make_unique<Participant>(*carrier.node, carrier.options);
    for (const StateListener& listener : listeners) {
      participant->add_listener(listener);
    }
    for (const ManagerListener& listener : manager_listeners) {
      participant->add_manager_listener(listener);
    }
    for (const Veto& veto : vetoes) {
      participant->add_veto(veto);
    }
    for (auto other = members.begin() + 1; other != members.end(); ++other) {
      participant->host(other->name, other->options.layers);
    }
  }
};

SharedParticipant& shared() {
  static SharedParticipant instance;
  return instance;
}

// A listener or veto joins the process (kept for a successor after a hand-over) and its
// participant, if it has one.
template <typename Handler>
void add_to_process(std::vector<Handler> SharedParticipant::*kept,
                    void (Participant::*add)(Handler), Handler handler) {
  SharedParticipant& process = shared();
  std::lock_guard<std::mutex> lock(process.mutex);
  (process.*kept).push_back(handler);
  if (process.participant) {
    ((*process.participant).*add)(std::move(handler));
  }
}

}  // namespace

ContextNode::ContextNode(rcl_node_t& node, ParticipantOptions options) : node_(&node) {
  SharedParticipant& process = shared();
  std::lock_guard<std::mutex> lock(process.mutex);
  process.members.push_back(Member{&node, rcl_node_get_fully_qualified_name(&node), options});
  try {
    if (!process.participant) {
      process.carry_by_first();
    } else {
      process.participant->host(process.members.back().name, options.layers);
    }
  } catch (...) {
    process.members.pop_back();
    throw;
  }
}

ContextNode::~ContextNode() {
  SharedParticipant& process = shared();
  std::unique_ptr<Participant> leaving;
  {
    std::lock_guard<std::mutex> lock(process.mutex);
    auto self = std::find_if(process.members.begin(), process.members.end(),
                             [this](const Member& member) { return member.node == node_; });
    if (self == process.members.end()) {
      return;
    }
    const bool carrier = self == process.members.begin();
    const std::string name = self->name;
    process.members.erase(self);
    if (!carrier) {
      if (process.participant) {  // null if a hand-over failed
        process.participant->release(name);
      }
      return;
    }
    leaving = std::move(process.participant);
  }
  std::optional<ParticipantProtocol> previous;
  if (leaving) {
    previous = leaving->protocol();
  }
  // Destroyed without the lock: its thread may be in a listener that takes it.
  leaving.reset();  // leaves
  std::lock_guard<std::mutex> lock(process.mutex);
  if (!process.participant && !process.members.empty()) {
    try {
      // The next node of the process takes over, from where the process stands.
      process.carry_by_first(previous ? &*previous : nullptr);
    } catch (const std::exception& error) {
      std::fprintf(stderr, "contextros: no hand-over of the participant: %s\n", error.what());
    } catch (...) {
      std::fprintf(stderr, "contextros: no hand-over of the participant\n");
    }
  }
}

void ContextNode::add_listener(StateListener listener) {
  add_to_process(&SharedParticipant::listeners, &Participant::add_listener, std::move(listener));
}

void ContextNode::add_manager_listener(ManagerListener listener) {
  add_to_process(&SharedParticipant::manager_listeners, &Participant::add_manager_listener,
                 std::move(listener));
}

void ContextNode::add_veto(Veto veto) {
  add_to_process(&SharedParticipant::vetoes, &Participant::add_veto, std::move(veto));
}

std::string ContextNode::carrier() {
  SharedParticipant& process = shared();
  std::lock_guard<std::mutex> lock(process.mutex);
  return process.participant ? process.participant->node_name() : std::string();
}

}  // namespace contextros::ros
