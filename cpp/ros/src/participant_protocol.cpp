#include "contextros/ros/participant_protocol.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <utility>

namespace contextros::ros {

// -- validation (the rules of src/contextros/protocol/validation.py) -----------------------

namespace {

constexpr std::size_t max_name_length = 128;
constexpr std::size_t max_layers = 256;
constexpr std::size_t max_token_length = 64;
constexpr std::size_t max_text_length = 1024;
constexpr std::size_t max_error_length = 1000;

std::string shown(const std::string& text) {
  std::string out = "'";
  for (char c : text.substr(0, 40)) {
    out += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? '?' : c;
  }
  return out + (text.size() > 40 ? "'..." : "'");
}

std::string layer_name_problem(const std::string& name, const std::string& field) {
  if (name.empty()) return field + " is empty";
  if (name.size() > max_name_length) {
    return field + " " + shown(name) + " is longer than " + std::to_string(max_name_length) +
           " characters";
  }
  if (!is_layer_name(name)) return field + " " + shown(name) + " is not an identifier";
  return "";
}

std::string text_problem(const std::string& text, const std::string& field, std::size_t limit) {
  if (text.size() > limit) {
    return field + " is longer than " + std::to_string(limit) + " characters";
  }
  const bool printable = std::none_of(text.begin(), text.end(), [](char c) {
    return static_cast<unsigned char>(c) < 0x20 || c == 0x7f;
  });
  return printable ? "" : field + " " + shown(text) + " has control characters";
}

// Free text as the manager accepts it (printable, bounded): an error message often spans
// lines, and a report the manager refuses would be worse than a flat one.
std::string printable(std::string text) {
  for (char& c : text) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  return text.substr(0, max_error_length);
}

}  // namespace

std::vector<std::string> relation_violations(const std::vector<std::string>& active,
                                             const std::vector<LayerInfo>& declarations) {
  const std::set<std::string> on(active.begin(), active.end());
  // The union of the declarations of one name (the stricter reading), as the manager merges.
  std::map<std::string, LayerInfo> merged;
  for (const LayerInfo& layer : declarations) {
    auto [entry, fresh] = merged.emplace(layer.name, layer);
    if (!fresh) {
      LayerInfo& known = entry->second;
      known.excludes.insert(known.excludes.end(), layer.excludes.begin(), layer.excludes.end());
      known.required.insert(known.required.end(), layer.required.begin(), layer.required.end());
      if (known.group.empty()) known.group = layer.group;
    }
  }
  auto excludes_of = [&](const std::string& name) {
    auto found = merged.find(name);
    return found == merged.end() ? std::set<std::string>()
                                 : std::set<std::string>(found->second.excludes.begin(),
                                                         found->second.excludes.end());
  };
  std::vector<std::string> problems;
  std::map<std::string, std::vector<std::string>> members;
  for (const std::string& name : on) {  // sorted, as Python's sorted(active_set)
    auto found = merged.find(name);
    if (found == merged.end()) continue;
    const LayerInfo& layer = found->second;
    for (const std::string& excluded : std::set<std::string>(layer.excludes.begin(),
                                                             layer.excludes.end())) {
      if (!on.count(excluded) || excluded == name) continue;
      const bool mutual = excludes_of(excluded).count(name) > 0;
      if (excluded > name || !mutual) {
        problems.push_back(name + " excludes " + excluded + ", both would be active");
      }
    }
    for (const std::string& required : std::set<std::string>(layer.required.begin(),
                                                             layer.required.end())) {
      if (!on.count(required)) {
        problems.push_back(name + " requires " + required + ", which would not be active");
      }
    }
    if (!layer.group.empty()) members[layer.group].push_back(name);
  }
  for (const auto& [group, names] : members) {
    if (names.size() > 1) {
      std::string listing;
      for (const std::string& name : names) listing += (listing.empty() ? "" : ", ") + name;
      problems.push_back("group '" + group + "' allows one active layer, would have " + listing);
    }
  }
  return problems;
}

std::vector<std::string> state_problems(const LayerState& state) {
  std::vector<std::string> problems;
  if (state.epoch > max_epoch) {
    problems.push_back("epoch " + std::to_string(state.epoch) +
                       " is beyond any epoch an honest manager issues (2**48)");
  }
  problems.push_back(text_problem(state.manager_id, "manager_id", max_token_length));
  problems.push_back(text_problem(state.requester, "requester", max_text_length));
  problems.push_back(text_problem(state.reason, "reason", max_text_length));
  if (state.active.size() > max_layers) {
    problems.push_back("active_layers lists " + std::to_string(state.active.size()) +
                       " names, more than " + std::to_string(max_layers));
  } else {
    int reported = 0;
    for (const std::string& name : state.active) {
      std::string problem = layer_name_problem(name, "active_layers entry");
      if (!problem.empty() && reported++ < 3) problems.push_back(std::move(problem));
    }
    if (std::set<std::string>(state.active.begin(), state.active.end()).size() !=
        state.active.size()) {
      problems.push_back("active_layers names a layer twice");
    }
  }
  problems.erase(std::remove(problems.begin(), problems.end(), std::string()), problems.end());
  return problems;
}

// -- the state machine ----------------------------------------------------------------------

namespace {

// The manager's `status_period` as a participant takes it: a number within bounds (0, NaN
// or negative: none).
Clock::duration asked_period(double seconds) {
  if (!(seconds > 0.0)) return Clock::duration::zero();
  const double bounded = std::min(seconds, static_cast<double>(max_status_period.count()));
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(bounded));
}

}  // namespace

ParticipantProtocol::ParticipantProtocol(std::string node, std::string incarnation,
                                         std::vector<LayerInfo> layers,
                                         Clock::duration heartbeat_period,
                                         Clock::duration manager_timeout,
                                         std::vector<Clock::duration> repeats)
    : node_(std::move(node)),
      incarnation_(std::move(incarnation)),
      layers_(std::move(layers)),
      heartbeat_period_(heartbeat_period),
      status_period_(heartbeat_period),
      manager_timeout_(manager_timeout),
      repeats_(std::move(repeats)) {}

std::uint64_t ParticipantProtocol::newest_epoch() const {
  return std::max({applied_epoch_, pending_epoch_, failed_epoch_});
}

ParticipantReport ParticipantProtocol::report(bool leaving) const {
  ParticipantReport report;
  report.node = node_;
  report.incarnation = incarnation_;
  report.layers = layers_;
  report.applied_epoch = applied_epoch_;
  report.active = active_;
  report.applied_manager_id = applied_manager_id_;
  report.in_critical_section = in_critical_section();
  report.pending_epoch = deferring() ? pending_epoch_ : 0;
  report.failed_epoch = failed_epoch_;
  report.error = error_;
  report.leaving = leaving;
  report.hosted = hosted_;
  report.manager_lost = manager_lost_;
  report.vote_epoch = vote_epoch_;
  report.vote_manager_id = vote_manager_id_;
  report.vote_yes = vote_yes_;
  report.vote_reason = vote_reason_;
  return report;
}

void ParticipantProtocol::continue_from(const ParticipantProtocol& previous) {
  applied_epoch_ = previous.applied_epoch_;
  applied_manager_id_ = previous.applied_manager_id_;
  active_ = previous.active_;
  failed_epoch_ = previous.failed_epoch_;
  error_ = previous.error_;
  manager_id_ = previous.manager_id_;
  manager_lost_ = previous.manager_lost_;
  manager_heard_ = previous.manager_heard_;
  status_period_ = previous.status_period_;
}

ParticipantActions ParticipantProtocol::announce(Clock::time_point now) {
  if (!manager_heard_) {
    manager_heard_ = now;  // the manager-lost clock starts with the node
  }
  return {send(now, Repeat::always)};
}

ParticipantActions ParticipantProtocol::receive_state(const LayerState& state,
                                                      std::optional<Clock::time_point> now) {
  std::vector<std::string> problems = state_problems(state);
  if (!problems.empty()) {
    problems.resize(std::min<std::size_t>(problems.size(), 5));
    return {StateRejected{std::move(problems)}};
  }
  if (now) {
    status_period_ = std::max(heartbeat_period_, asked_period(state.status_period));
  }
  ParticipantActions actions = heard_manager(state.manager_id, now);
  if (state.epoch == 0 || state.epoch <= newest_epoch()) {
    return actions;  // no state yet (a recovering manager's heartbeat), or stale
  }
  actions.emplace_back(ApplyState{state});
  return actions;
}

namespace {
// The managers whose newest proposal voted on a participant remembers (as in Python).
constexpr std::size_t voted_managers = 8;
}  // namespace

bool ParticipantProtocol::wants_vote(const LayerState& proposal) const {
  std::uint64_t newest_voted = 0;
  for (const auto& [manager, epoch] : voted_) {
    if (manager == proposal.manager_id) newest_voted = epoch;
  }
  return proposal.epoch > std::max(newest_epoch(), newest_voted) &&
         state_problems(proposal).empty();
}

ParticipantActions ParticipantProtocol::receive_proposal(const LayerState& proposal,
                                                         Clock::time_point now,
                                                         std::string_view veto, bool vote) {
  std::vector<std::string> problems = state_problems(proposal);
  if (!problems.empty()) {
    problems.resize(std::min<std::size_t>(problems.size(), 5));
    return {StateRejected{std::move(problems)}};
  }
  ParticipantActions actions = heard_manager(proposal.manager_id, now);
  if (!vote || !wants_vote(proposal)) {
    return actions;  // stale, or already voted (every report repeats the vote)
  }
  std::vector<std::string> reasons;
  if (!veto.empty()) reasons.emplace_back(veto);
  if (in_critical_section()) reasons.emplace_back("in a critical section");
  for (std::string& problem : relation_violations(proposal.active, layers_)) {
    reasons.push_back(std::move(problem));
  }
  std::string reason;
  for (const std::string& part : reasons) reason += (reason.empty() ? "" : "; ") + part;
  vote_epoch_ = proposal.epoch;
  vote_manager_id_ = proposal.manager_id;
  voted_.erase(std::remove_if(voted_.begin(), voted_.end(),
                              [&](const auto& entry) { return entry.first == proposal.manager_id; }),
               voted_.end());
  voted_.emplace_back(proposal.manager_id, proposal.epoch);
  if (voted_.size() > voted_managers) voted_.erase(voted_.begin());
  vote_yes_ = reasons.empty();
  vote_reason_ = printable(std::move(reason));
  actions.emplace_back(send(now, Repeat::if_lossy));
  return actions;
}

ParticipantActions ParticipantProtocol::applied(const LayerState& state, Clock::time_point now) {
  if (state.epoch <= applied_epoch_) {
    return {};  // a deferred older switch settling after a newer one applied directly
  }
  applied_epoch_ = state.epoch;
  applied_manager_id_ = state.manager_id;
  active_ = state.active;
  return {send(now, Repeat::if_lossy)};
}

ParticipantActions ParticipantProtocol::deferred(const LayerState& state, Clock::time_point now) {
  pending_epoch_ = std::max(pending_epoch_, state.epoch);
  return {send(now, Repeat::if_lossy)};
}

ParticipantActions ParticipantProtocol::failed(const LayerState& state, std::string_view error,
                                               Clock::time_point now) {
  if (state.epoch <= applied_epoch_) {
    return {};  // an older deferred switch failing after a newer one applied: moot
  }
  failed_epoch_ = std::max(failed_epoch_, state.epoch);
  error_ = printable("epoch " + std::to_string(state.epoch) + ": " + std::string(error));
  return {send(now, Repeat::if_lossy)};
}

ParticipantActions ParticipantProtocol::host(std::vector<std::string> hosted,
                                             std::vector<LayerInfo> layers,
                                             Clock::time_point now) {
  hosted_ = std::move(hosted);
  layers_ = std::move(layers);
  return {send(now, Repeat::if_lossy)};
}

ParticipantActions ParticipantProtocol::tick(Clock::time_point now) {
  ParticipantActions actions;
  if (!manager_heard_) {
    manager_heard_ = now;
  }
  const Clock::duration silent = now - *manager_heard_;
  if (!manager_lost_ && silent > manager_timeout_) {
    manager_lost_ = true;
    loss_seen_ = now;
    status_period_ = heartbeat_period_;  // whichever manager comes next
    actions.emplace_back(ManagerLost{silent});
  }
  const bool due_repeat = !repeat_at_.empty() && now >= repeat_at_.front();
  // 80% of the period: a timer firing a little early must not skip a whole beat (the Python
  // participant did, and lost every other heartbeat).
  const bool due_beat = !last_sent_ || now - *last_sent_ >= status_period_ * 4 / 5;
  if (due_repeat || due_beat || !actions.empty()) {
    repeat_at_.erase(std::remove_if(repeat_at_.begin(), repeat_at_.end(),
                                    [&](Clock::time_point at) { return at <= now; }),
                     repeat_at_.end());
    actions.emplace_back(send(now));
  }
  return actions;
}

ParticipantActions ParticipantProtocol::leave() const { return {PublishStatus{report(true)}}; }

Clock::time_point ParticipantProtocol::next_tick() const {
  if (!last_sent_) {
    return Clock::time_point::min();
  }
  Clock::time_point next = *last_sent_ + status_period_;
  if (!repeat_at_.empty()) {
    next = std::min(next, repeat_at_.front());
  }
  if (manager_heard_ && !manager_lost_) {
    next = std::min(next, *manager_heard_ + manager_timeout_ + std::chrono::milliseconds(1));
  }
  return next;
}

ParticipantActions ParticipantProtocol::heard_manager(const std::string& manager_id,
                                                      std::optional<Clock::time_point> now) {
  if (!now) {
    return {};
  }
  ParticipantActions actions;
  if (last_message_ && *now - *last_message_ > heartbeat_period_ * 8 / 5) {
    loss_seen_ = now;
  }
  manager_heard_ = now;
  last_message_ = now;
  const bool new_manager = !manager_id.empty() && manager_id != manager_id_;
  if (!manager_id.empty()) {
    manager_id_ = manager_id;
  }
  if (manager_lost_) {
    manager_lost_ = false;
    actions.emplace_back(ManagerFound{manager_id});
  }
  if (new_manager || !actions.empty()) {
    // A (re)started or regained manager learns about this node at once, not at the next
    // heartbeat: its recovery and our rejoining are faster.
    actions.emplace_back(send(*now, Repeat::always));
  }
  return actions;
}

PublishStatus ParticipantProtocol::send(Clock::time_point now, Repeat repeat) {
  last_sent_ = now;
  const bool lossy = loss_seen_ && now - *loss_seen_ < loss_memory;
  if (repeat == Repeat::always || (repeat == Repeat::if_lossy && lossy)) {
    repeat_at_.clear();
    for (Clock::duration delay : repeats_) {
      repeat_at_.push_back(now + delay);
    }
  }
  return PublishStatus{report()};
}

}  // namespace contextros::ros
