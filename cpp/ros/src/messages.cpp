// Messages <-> protocol values (the twin of src/contextros/ros/messages.py).
#include "messages.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace contextros::ros {

namespace msg = contextros_interfaces::msg;

namespace {

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
  info.implies = sorted(layer.implies);
  return info;
}

}  // namespace

LayerState state_from_msg(const msg::LayerState& state) {
  return LayerState{state.epoch,
                    state.active_layers,
                    state.requester,
                    state.reason,
                    state.manager_id,
                    state.stamp.sec + state.stamp.nanosec * 1e-9,
                    state.status_period};
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

}  // namespace contextros::ros
