// Names and QoS of the protocol's topics (docs/protocol.md), in one place for C++; the
// Python twin is src/contextros/ros/topics.py.
#pragma once

#include <rmw/types.h>

namespace contextros::ros {

// Relative names: rcl resolves them against the node's namespace, so a node in the
// default namespace `/` uses `/contextros/state` exactly as the Python side does.
inline constexpr const char* state_topic = "contextros/state";
inline constexpr const char* heartbeat_topic = "contextros/heartbeat";
inline constexpr const char* proposal_topic = "contextros/proposal";
inline constexpr const char* status_topic = "contextros/status";
// The manager's services (the activation client, contextros/ros/client.hpp).
inline constexpr const char* activate_service = "contextros/activate";
inline constexpr const char* query_service = "contextros/query";

// Only the newest state matters (full snapshots), and a late joiner must get it at once.
rmw_qos_profile_t state_qos();
// The manager's heartbeat (its current state, repeated): best effort, depth 1.
rmw_qos_profile_t heartbeat_qos();
// Atomic activations' proposals, repeated until the vote ends: best effort, as the heartbeat.
rmw_qos_profile_t proposal_qos();
// Participants' reports: complete and repeated, so best effort (a reliable writer would
// hold newer reports behind a lost one on a lossy link; docs/protocol.md).
rmw_qos_profile_t status_qos();

}  // namespace contextros::ros
