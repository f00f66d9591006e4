// The participant's side of the protocol, without ROS: never back to an older epoch,
// honest acknowledgements. The same cases as tests/protocol/test_participant_protocol.py,
// so the C++ and Python participants decide alike.
#include <gtest/gtest.h>

#include <variant>

#include "contextros/ros/participant_protocol.hpp"

namespace contextros::ros {
namespace {

using namespace std::chrono_literals;

const Clock::time_point t0{};

ParticipantProtocol participant() {
  return ParticipantProtocol("/p", "inc-1", {LayerInfo{"Night", {}, {}, {}, ""}}, 250ms);
}

LayerState state(std::uint64_t epoch, std::vector<std::string> active = {}) {
  return LayerState{epoch, std::move(active), "", "", "m1"};
}

ParticipantReport only_report(const ParticipantActions& actions) {
  EXPECT_EQ(actions.size(), 1u);
  const auto* publish = std::get_if<PublishStatus>(&actions.at(0));
  if (publish == nullptr) {
    throw std::logic_error("expected a PublishStatus");
  }
  return publish->report;
}

TEST(ParticipantProtocol, NewStateIsAppliedAndAcknowledged) {
  ParticipantProtocol p = participant();
  const ParticipantActions actions = p.receive_state(state(3, {"Night"}));
  ASSERT_EQ(actions.size(), 1u);
  ASSERT_TRUE(std::holds_alternative<ApplyState>(actions[0]));
  EXPECT_EQ(std::get<ApplyState>(actions[0]).state.epoch, 3u);
  const ParticipantReport report = only_report(p.applied(state(3, {"Night"}), t0));
  EXPECT_EQ(report.applied_epoch, 3u);
  EXPECT_EQ(report.active, std::vector<std::string>{"Night"});
  EXPECT_EQ(report.applied_manager_id, "m1");
  EXPECT_EQ(report.node, "/p");
  EXPECT_EQ(report.incarnation, "inc-1");
}

TEST(ParticipantProtocol, StaleAndDuplicateStatesAreIgnored) {
  ParticipantProtocol p = participant();
  p.applied(state(5, {"Night"}), t0);
  EXPECT_TRUE(p.receive_state(state(4)).empty());
  EXPECT_TRUE(p.receive_state(state(5, {"Night"})).empty());
  EXPECT_TRUE(p.applied(state(4), t0 + 100ms).empty());
  EXPECT_EQ(p.applied_epoch(), 5u);
}

TEST(ParticipantProtocol, DeferredStateIsPendingAndAcknowledgedOnlyOnceApplied) {
  ParticipantProtocol p = participant();
  const ParticipantReport deferred = only_report(p.deferred(state(2, {"Night"}), t0));
  EXPECT_TRUE(deferred.in_critical_section);
  EXPECT_EQ(deferred.pending_epoch, 2u);
  EXPECT_EQ(deferred.applied_epoch, 0u);
  EXPECT_TRUE(p.receive_state(state(2, {"Night"})).empty()) << "a scheduled epoch is not applied twice";
  const ParticipantReport applied = only_report(p.applied(state(2, {"Night"}), t0 + 500ms));
  EXPECT_EQ(applied.applied_epoch, 2u);
  EXPECT_FALSE(applied.in_critical_section);
  EXPECT_EQ(applied.pending_epoch, 0u);
}

TEST(ParticipantProtocol, NewerStateWhileDeferredIsPassedOnBehindIt) {
  ParticipantProtocol p = participant();
  p.deferred(state(2, {"Night"}), t0);
  const ParticipantActions actions = p.receive_state(state(3));
  ASSERT_EQ(actions.size(), 1u);
  EXPECT_EQ(std::get<ApplyState>(actions[0]).state.epoch, 3u);
}

TEST(ParticipantProtocol, FailureIsReportedAndNotRetried) {
  ParticipantProtocol p = participant();
  const ParticipantReport report = only_report(p.failed(state(2, {"Night"}), "Night requires Dark", t0));
  EXPECT_EQ(report.failed_epoch, 2u);
  EXPECT_EQ(report.error, "epoch 2: Night requires Dark");
  EXPECT_TRUE(p.receive_state(state(2, {"Night"})).empty());
}

TEST(ParticipantProtocol, AnOlderDeferredSwitchFailingAfterANewerAppliedIsMoot) {
  ParticipantProtocol p = participant();
  p.applied(state(4), t0);
  EXPECT_TRUE(p.failed(state(3), "late", t0).empty());
  EXPECT_EQ(p.report().failed_epoch, 0u);
}

TEST(ParticipantProtocol, ReportsAreRepeatedOnlyWhileTheLinkShowsLoss) {
  ParticipantProtocol p = participant();
  p.announce(t0);
  for (int beat = 1; beat < 5; ++beat) {  // the manager's heartbeat, on time: a clean link
    p.receive_state(state(1), t0 + beat * 250ms);
    p.tick(t0 + beat * 250ms);
  }
  p.applied(state(2, {"Night"}), t0 + 1000ms);
  EXPECT_TRUE(p.tick(t0 + 1050ms).empty()) << "a clean link: no repeat, the manager is not loaded";
  p.receive_state(state(2, {"Night"}), t0 + 1500ms);  // 0.5 s after the last: one lost
  EXPECT_EQ(only_report(p.applied(state(3), t0 + 1600ms)).applied_epoch, 3u);
  EXPECT_EQ(only_report(p.tick(t0 + 1650ms)).applied_epoch, 3u) << "repeated: loss was seen";
  EXPECT_EQ(p.tick(t0 + 1750ms).size(), 1u);
  for (int beat = 1; beat < 130; ++beat) {  // 32 s of heartbeats on time: the loss is forgotten
    p.receive_state(state(3), t0 + 1600ms + beat * 250ms);
  }
  p.applied(state(4, {"Night"}), t0 + 34s);
  EXPECT_TRUE(p.tick(t0 + 34050ms).empty());
}

TEST(ParticipantProtocol, ASuccessorCarriesOnFromTheParticipantItReplaces) {
  // The carrier node of a process goes; the next node carries a new participant (a new
  // incarnation) for the same process, whose layers are still those applied before.
  ParticipantProtocol previous = participant();
  previous.receive_state(state(5, {"Night"}), t0);
  previous.applied(state(5, {"Night"}), t0);
  ParticipantProtocol successor("/q", "inc-2", {LayerInfo{"Night", {}, {}, {}, ""}});
  successor.continue_from(previous);
  const ParticipantReport report = only_report(successor.announce(t0 + 1s));
  EXPECT_EQ(report.applied_epoch, 5u);
  EXPECT_EQ(report.active, std::vector<std::string>{"Night"});
  EXPECT_EQ(report.applied_manager_id, "m1");
  EXPECT_TRUE(successor.receive_state(state(4), t0 + 1100ms).empty()) << "never back a state";
  EXPECT_TRUE(successor.receive_state(state(5, {"Night"}), t0 + 1200ms).empty());
  const ParticipantActions newer = successor.receive_state(state(6), t0 + 1300ms);
  ASSERT_EQ(newer.size(), 1u);
  EXPECT_TRUE(std::holds_alternative<ApplyState>(newer[0]));
}

TEST(ParticipantProtocol, HeartbeatPeriodAndRepeatsOfANewReport) {
  ParticipantProtocol p = participant();
  EXPECT_EQ(p.announce(t0).size(), 1u);
  EXPECT_EQ(p.next_tick(), t0 + 50ms);
  EXPECT_EQ(p.tick(t0 + 50ms).size(), 1u) << "repeated shortly after: a lossy link may have lost it";
  EXPECT_TRUE(p.tick(t0 + 100ms).empty());
  EXPECT_EQ(p.tick(t0 + 150ms).size(), 1u);
  EXPECT_EQ(p.next_tick(), t0 + 400ms);
  EXPECT_TRUE(p.tick(t0 + 300ms).empty());
  EXPECT_EQ(p.tick(t0 + 410ms).size(), 1u) << "then the heartbeat";
  EXPECT_TRUE(only_report(p.leave()).leaving);
}

TEST(ParticipantProtocol, TheHeartbeatPeriodIsTheLongerOneTheManagerAsksFor) {
  ParticipantProtocol p("/p", "inc-1", {LayerInfo{"Night", {}, {}, {}, ""}}, 250ms, 3s);
  p.announce(t0);
  p.tick(t0 + 50ms);  // the announcement's repeats
  p.tick(t0 + 150ms);
  LayerState slower = state(1);
  slower.status_period = 2.0;  // many participants: the manager asks for a status every 2 s
  p.receive_state(slower, t0 + 200ms);  // a new manager: reported at once, and repeated
  p.applied(slower, t0 + 200ms);
  p.tick(t0 + 250ms);
  EXPECT_EQ(only_report(p.tick(t0 + 350ms)).applied_epoch, 1u) << "reported last at 350 ms";
  EXPECT_EQ(p.status_period(), 2s);
  EXPECT_EQ(p.next_tick(), t0 + 2350ms);
  EXPECT_TRUE(p.tick(t0 + 1000ms).empty()) << "no heartbeat every 0.25 s any more";
  p.receive_state(slower, t0 + 1500ms);  // its heartbeat: the manager is still there
  EXPECT_TRUE(p.tick(t0 + 1900ms).empty());
  EXPECT_EQ(only_report(p.tick(t0 + 1950ms)).applied_epoch, 1u) << "after 80% of the period";
  LayerState faster = state(1);
  faster.status_period = 0.1;  // never below the node's own period
  p.receive_state(faster, t0 + 1960ms);
  EXPECT_EQ(p.status_period(), 250ms);
  LayerState forged = state(1);
  forged.status_period = 1e9;  // a forged period silences the node for a minute at most
  p.receive_state(forged, t0 + 1970ms);
  EXPECT_EQ(p.status_period(), 60s);
  ParticipantActions lost = p.tick(t0 + 5s);
  ASSERT_EQ(lost.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<ManagerLost>(lost[0]));
  EXPECT_EQ(p.status_period(), 250ms) << "the manager lost: back to its own period";
}

TEST(ParticipantProtocol, AManagerSilentForItsTimeoutIsLostThenFoundAgain) {
  ParticipantProtocol p("/p", "inc-1", {LayerInfo{"Night", {}, {}, {}, ""}}, 250ms, 2s);
  p.announce(t0);
  p.receive_state(state(1), t0 + 100ms);
  p.applied(state(1), t0 + 100ms);
  EXPECT_FALSE(p.manager_lost());
  ParticipantActions lost = p.tick(t0 + 2200ms);
  ASSERT_EQ(lost.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<ManagerLost>(lost[0]));
  EXPECT_TRUE(std::get<PublishStatus>(lost[1]).report.manager_lost);
  for (const ParticipantAction& action : p.tick(t0 + 2600ms)) {
    EXPECT_FALSE(std::holds_alternative<ManagerLost>(action)) << "lost is said once";
  }
  // A heartbeat (the same epoch again) is enough to hear it: no new state to apply.
  ParticipantActions found = p.receive_state(state(1), t0 + 3s);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(std::get<ManagerFound>(found[0]).manager_id, "m1");
  EXPECT_FALSE(std::get<PublishStatus>(found[1]).report.manager_lost);
}

TEST(ParticipantProtocol, ANewManagerHearsFromTheNodeAtOnce) {
  ParticipantProtocol p = participant();
  p.announce(t0);
  ParticipantActions first = p.receive_state(LayerState{0, {}, "", "", "m2"}, t0 + 10ms);
  ASSERT_EQ(first.size(), 1u) << "epoch 0 (a recovering manager) is nothing to apply";
  EXPECT_TRUE(std::holds_alternative<PublishStatus>(first[0]));
  EXPECT_TRUE(p.receive_state(LayerState{0, {}, "", "", "m2"}, t0 + 20ms).empty());
}

TEST(ParticipantProtocol, BadStatesAreIgnoredAndDoNotPoisonIt) {
  const std::vector<std::pair<std::string, LayerState>> bad = {
      {"epoch", LayerState{~std::uint64_t{0}, {"Night"}, "", "", "m"}},
      {"epoch", LayerState{1000000000000000ull, {"Night"}, "", "", "m"}},
      {"active_layers", LayerState{5, {std::string("Night\0evil", 10)}, "", "", "m"}},
      {"active_layers", LayerState{5, {"Night", "Night"}, "", "", "m"}},
      {"active_layers", LayerState{5, {"Ni ght"}, "", "", "m"}},
      {"active_layers", LayerState{5, {"Night\xff"}, "", "", "m"}},
      {"active_layers", LayerState{5, {"\xc3\x97"}, "", "", "m"}},
      {"active_layers", LayerState{5, std::vector<std::string>(300, "L"), "", "", "m"}},
      {"manager_id", LayerState{5, {"Night"}, "", "", std::string("m\0", 2)}},
      {"requester", LayerState{5, {"Night"}, std::string(2000, 'x'), "", "m"}},
      {"reason", LayerState{5, {"Night"}, "", "a\nb", "m"}},
  };
  for (const auto& [field, message] : bad) {
    ParticipantProtocol p = participant();
    const ParticipantActions actions = p.receive_state(message, t0 + 1s);
    ASSERT_EQ(actions.size(), 1u) << field;
    const auto* rejected = std::get_if<StateRejected>(&actions[0]);
    ASSERT_NE(rejected, nullptr) << field;
    bool named = false;
    for (const std::string& problem : rejected->problems) {
      named = named || problem.find(field) != std::string::npos;
    }
    EXPECT_TRUE(named) << field << ": " << rejected->problems.front();
    const ParticipantActions good = p.receive_state(state(6, {"Night"}), t0 + 2s);
    EXPECT_TRUE(std::holds_alternative<ApplyState>(good.back())) << "not poisoned by " << field;
  }
}

TEST(ParticipantProtocol, AnOpenCriticalSectionIsReportedWithNothingDeferred) {
  ParticipantProtocol p = participant();
  p.set_critical_section_open(true);
  const ParticipantReport report = only_report(p.announce(t0));
  EXPECT_TRUE(report.in_critical_section);
  EXPECT_EQ(report.pending_epoch, 0u);
}

TEST(ParticipantProtocol, HostingOtherNodesReannouncesWithTheirLayers) {
  ParticipantProtocol p("/host", "1", {LayerInfo{"Indoor", {}, {}, {}, ""}});
  const ParticipantReport report = only_report(
      p.host({"/guest"}, {LayerInfo{"Indoor", {}, {}, {}, ""}, LayerInfo{"Night", {}, {}, {}, ""}},
             t0 + 1s));
  EXPECT_EQ(report.hosted, std::vector<std::string>{"/guest"});
  ASSERT_EQ(report.layers.size(), 2u);
  EXPECT_EQ(report.layers[1].name, "Night");
}

TEST(ParticipantProtocol, AnErrorSpanningLinesIsReportedFlat) {
  ParticipantProtocol p = participant();
  const ParticipantReport report =
      only_report(p.failed(state(2, {"Night"}), "line one\nline two", t0));
  EXPECT_NE(report.error.find("line one line two"), std::string::npos) << report.error;
}

// tests/protocol/test_participant_protocol.py::test_a_vote_is_yes_unless_...
TEST(ParticipantProtocol, AVoteIsYesUnlessACriticalSectionOrARelationSaysNo) {
  ParticipantProtocol p("/p", "1", {LayerInfo{"Gps", {}, {"Outdoor"}, {}, ""}}, 250ms, 3s, {});
  p.receive_state(state(0), t0);  // a recovering manager's heartbeat: m1 is heard
  EXPECT_TRUE(p.wants_vote(state(2, {"Outdoor", "Gps"})));
  const ParticipantReport yes = only_report(p.receive_proposal(state(2, {"Outdoor", "Gps"}), t0));
  EXPECT_FALSE(p.wants_vote(state(2, {"Outdoor", "Gps"}))) << "the vetoes are asked once";
  EXPECT_EQ(yes.vote_epoch, 2u);
  EXPECT_EQ(yes.vote_manager_id, "m1");
  EXPECT_TRUE(yes.vote_yes);
  EXPECT_TRUE(p.receive_proposal(state(2, {"Outdoor", "Gps"}), t0 + 100ms).empty())
      << "voted once";
  EXPECT_EQ(p.applied_epoch(), 0u) << "a vote changes nothing";
  const ParticipantReport no = only_report(p.receive_proposal(state(3, {"Gps"}), t0 + 200ms));
  EXPECT_FALSE(no.vote_yes);
  EXPECT_EQ(no.vote_reason, "Gps requires Outdoor, which would not be active");
  p.set_critical_section_open(true);
  const ParticipantReport busy =
      only_report(p.receive_proposal(state(4, {"Outdoor"}), t0 + 300ms, "arm moving"));
  EXPECT_EQ(busy.vote_reason, "arm moving; in a critical section");
  // A late copy of an older proposal, after a newer one was voted on, is over.
  EXPECT_FALSE(p.wants_vote(state(3, {"Gps"}))) << "a late copy of an older one";
  EXPECT_TRUE(p.receive_proposal(state(3, {"Gps"}), t0 + 400ms).empty());
  EXPECT_EQ(p.report().vote_epoch, 4u);
}

TEST(ParticipantProtocol, RelationViolationsReadAsThePythonOnes) {
  const std::vector<LayerInfo> layers{LayerInfo{"Slow", {"Fast"}, {}, {}, ""},
                                      LayerInfo{"Fast", {}, {}, {}, ""},
                                      LayerInfo{"Indoor", {}, {}, {}, "location"},
                                      LayerInfo{"Outdoor", {}, {}, {}, "location"}};
  EXPECT_EQ(relation_violations({"Slow", "Fast", "Indoor", "Outdoor"}, layers),
            (std::vector<std::string>{"Slow excludes Fast, both would be active",
                                      "group 'location' allows one active layer, would have "
                                      "Indoor, Outdoor"}));
}

TEST(ParticipantProtocol, LayerNamesBeyondAsciiAreAcceptedAsTheRuntimeDoes) {
  const LayerState state{5, {"\xc3\x9c" "berland"}, "", "", "m"};
  EXPECT_TRUE(contextros::ros::state_problems(state).empty());
  EXPECT_EQ(contextros::is_layer_name(state.active[0]), true);
}

}  // namespace
}  // namespace contextros::ros
