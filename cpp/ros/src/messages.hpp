// Messages <-> protocol values (the twin of src/contextros/ros/messages.py); internal to the
// participant.
#pragma once

#include <contextros/ros/participant_protocol.hpp>
#include <contextros_interfaces/msg/layer_state.hpp>
#include <contextros_interfaces/msg/participant_status.hpp>

namespace contextros::ros {

LayerState state_from_msg(const contextros_interfaces::msg::LayerState& state);
contextros_interfaces::msg::ParticipantStatus report_to_msg(const ParticipantReport& report);

}  // namespace contextros::ros
