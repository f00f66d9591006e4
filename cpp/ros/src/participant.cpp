// The Participant handle: starts the participant (its Impl and thread) on an rcl node, says
// what it hosts, and leaves when destroyed.
#include "contextros/ros/participant.hpp"

#include <algorithm>
#include <mutex>
#include <thread>
#include <utility>

#include "participant_impl.hpp"

namespace contextros::ros {

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

}  // namespace contextros::ros
