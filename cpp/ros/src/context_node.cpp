// One participant per process: the first ContextNode carries it, the others are hosted;
// when the carrier goes, the next node takes over from where the process stands.
#include <rcl/rcl.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "contextros/ros/participant.hpp"

namespace contextros::ros {

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
  // The carrier left and its participant is being closed: the next node takes over from
  // it (its protocol), so a node joining meanwhile only joins `members`.
  bool handing_over = false;

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
    if (process.participant) {
      process.participant->host(process.members.back().name, options.layers);
    } else if (!process.handing_over) {
      process.carry_by_first();
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
    process.handing_over = leaving != nullptr;
  }
  std::optional<ParticipantProtocol> previous;
  if (leaving) {
    previous = leaving->protocol();
  }
  // Destroyed without the lock: its thread may be in a listener that takes it.
  leaving.reset();  // leaves
  std::lock_guard<std::mutex> lock(process.mutex);
  process.handing_over = false;
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
