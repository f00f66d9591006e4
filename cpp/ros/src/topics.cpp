// The protocol topics' QoS (topics.hpp; docs/protocol.md).
#include "contextros/ros/topics.hpp"

#include <rmw/qos_profiles.h>

#include <cstddef>

namespace contextros::ros {

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

}  // namespace contextros::ros
