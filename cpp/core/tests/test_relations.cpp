// Relations and decisive activation: the rules of the Python core (configuration.py).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "contextros/contextros.hpp"
#include "fixtures.hpp"

using contextros::SwitchStatus;

namespace {

void define(const std::string& name, std::vector<std::string> excludes = {},
            std::vector<std::string> required = {}, std::string group = "",
            std::vector<std::string> after = {}) {
  contextros::define_layer({name, std::move(excludes), std::move(required), std::move(after),
                            std::move(group)});
}

class Relations : public RuntimeTest {};

TEST_F(Relations, ActivationOrderIsNewestLast) {
  contextros::activate("RelA");
  contextros::activate("RelB");
  contextros::activate("RelA");  // an active layer keeps its place
  EXPECT_EQ(contextros::active_layers(), (Names{"RelA", "RelB"}));
  contextros::deactivate("RelA");
  EXPECT_EQ(contextros::active_layers(), (Names{"RelB"}));
}

TEST_F(Relations, ExcludesIsSymmetricAndChangesNothing) {
  define("Ex1", {"Ex2"});
  define("Ex2");
  ASSERT_EQ(contextros::activate("Ex2").status, SwitchStatus::applied);
  const auto epoch = contextros::current_epoch();
  const auto outcome = contextros::activate("Ex1");
  EXPECT_EQ(outcome.status, SwitchStatus::failed);
  EXPECT_NE(outcome.error.find("Ex1 and Ex2 cannot be active together"), std::string::npos)
      << outcome.error;
  EXPECT_EQ(contextros::active_layers(), (Names{"Ex2"}));
  EXPECT_EQ(contextros::current_epoch(), epoch);
  // The other way round: Ex2 declares nothing, Ex1's exclusion still holds.
  EXPECT_EQ(contextros::set_active({"Ex2", "Ex1"}).status, SwitchStatus::failed);
}

TEST_F(Relations, RequiredLayersMustBeActive) {
  define("Needs", {}, {"Needed"});
  define("Needed");
  auto outcome = contextros::activate("Needs");
  EXPECT_EQ(outcome.status, SwitchStatus::failed);
  EXPECT_NE(outcome.error.find("Needs requires Needed"), std::string::npos) << outcome.error;
  EXPECT_EQ(contextros::set_active({"Needed", "Needs"}).status, SwitchStatus::applied);
  // Deactivating what another active layer requires fails too.
  EXPECT_EQ(contextros::deactivate("Needed").status, SwitchStatus::failed);
  EXPECT_EQ(contextros::active_layers(), (Names{"Needed", "Needs"}));
}

TEST_F(Relations, GroupMembersReplaceEachOther) {
  define("Inside", {}, {}, "place");
  define("Outside", {}, {}, "place");
  contextros::activate("Other");
  contextros::activate("Inside");
  contextros::activate("Outside");
  EXPECT_EQ(contextros::active_layers(), (Names{"Other", "Outside"}));
  auto outcome = contextros::set_active({"Inside", "Outside"});
  EXPECT_EQ(outcome.status, SwitchStatus::failed);
  EXPECT_NE(outcome.error.find("exclusive group 'place'"), std::string::npos) << outcome.error;
}

TEST_F(Relations, UnchangedConfigurationKeepsTheEpoch) {
  contextros::activate("Same");
  const auto epoch = contextros::current_epoch();
  const auto outcome = contextros::activate("Same");
  EXPECT_EQ(outcome.status, SwitchStatus::applied);
  EXPECT_EQ(outcome.epoch, epoch);
  EXPECT_EQ(contextros::activate("Different").epoch, epoch + 1);
}

TEST_F(Relations, SetActiveRefusesBadNamesAndDuplicates) {
  auto outcome = contextros::set_active({"not a name"});
  EXPECT_EQ(outcome.status, SwitchStatus::failed);
  EXPECT_NE(outcome.error.find("'not a name' is not a layer name"), std::string::npos);
  outcome = contextros::set_active({"Twice", "Twice"});
  EXPECT_EQ(outcome.status, SwitchStatus::failed);
  EXPECT_NE(outcome.error.find("listed twice"), std::string::npos);
  EXPECT_TRUE(contextros::active_layers().empty());
}

TEST_F(Relations, CallbackIsCalledBeforeReturningWhenNotDeferred) {
  int calls = 0;
  SwitchStatus seen = SwitchStatus::deferred;
  contextros::set_active({"Cb"}, [&](const contextros::SwitchOutcome& outcome) {
    ++calls;
    seen = outcome.status;
  });
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(seen, SwitchStatus::applied);
}

TEST_F(Relations, InconsistentDefinitionsAreRefused) {
  EXPECT_THROW(define("Self", {"Self"}), contextros::LayerDefinitionError);
  EXPECT_THROW(define("Both", {"X"}, {"X"}), contextros::LayerDefinitionError);
  EXPECT_THROW(define("bad name"), contextros::LayerDefinitionError);
  EXPECT_THROW(define("Grouped", {}, {}, "not-a-group"), contextros::LayerDefinitionError);
}

TEST_F(Relations, DefinedLayersListsTheLatestDefinition) {
  define("Listed", {"Ex2"});
  define("Listed", {}, {}, "", {"Ex2"});
  bool found = false;
  for (const auto& layer : contextros::defined_layers()) {
    if (layer.name != "Listed") continue;
    found = true;
    EXPECT_TRUE(layer.excludes.empty());
    EXPECT_EQ(layer.after, (Names{"Ex2"}));
  }
  EXPECT_TRUE(found);
}

TEST_F(Relations, ObserversSeeAppliedSwitchesInOrder) {
  std::vector<contextros::SwitchEvent> events;
  {
    auto subscription = contextros::subscribe([&](const auto& event) { events.push_back(event); });
    contextros::activate("Obs1");
    contextros::activate("Obs1");  // unchanged: no event
    contextros::set_active({"Obs2"});
    contextros::activate("not a name");  // failed: no event
  }
  contextros::activate("Obs3");  // unsubscribed
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].old_layers, Names{});
  EXPECT_EQ(events[0].new_layers, (Names{"Obs1"}));
  EXPECT_EQ(events[1].old_layers, (Names{"Obs1"}));
  EXPECT_EQ(events[1].new_layers, (Names{"Obs2"}));
  EXPECT_EQ(events[1].epoch, events[0].epoch + 1);
}

TEST_F(Relations, ActivationOrderFollowsDeclaredAfter) {
  define("OrdBase");
  define("OrdMiddle", {}, {}, "", {"OrdBase"});
  define("OrdTop", {}, {}, "", {"OrdMiddle"});
  EXPECT_EQ(contextros::activation_order({"OrdTop", "Unrelated", "OrdBase", "OrdMiddle"}),
            (Names{"Unrelated", "OrdBase", "OrdMiddle", "OrdTop"}));
  define("OrdCycle1", {}, {}, "", {"OrdCycle2"});
  define("OrdCycle2", {}, {}, "", {"OrdCycle1"});
  EXPECT_THROW(contextros::activation_order({"OrdCycle1", "OrdCycle2"}), contextros::RelationError);
}

}  // namespace

namespace {

// One rule for layer names, as Python's str.isidentifier() (the participant's validation
// uses it too).
TEST_F(Relations, LayerNamesAreIdentifiersInUtf8) {
  for (const char* good : {"Indoor", "_x1", "\xc3\x9c" "berland", "\xe5\xa4\x9c\xe9\x96\x93",
                           "a\xc2\xb5"}) {
    EXPECT_TRUE(contextros::is_layer_name(good)) << good;
  }
  for (const char* bad : {"", "1a", "a-b", "a b", "\xff", "a\xc3", "\xc0\xae", "a\xc2\xa0" "b",
                          "\xed\xa0\x80", "a\xc3\x97" "b"}) {
    EXPECT_FALSE(contextros::is_layer_name(bad)) << bad;
  }
  EXPECT_EQ(contextros::set_active({"\xc3\x9c" "berland"}).status, SwitchStatus::applied);
  EXPECT_EQ(contextros::active_layers(), Names{"\xc3\x9c" "berland"});
}

}  // namespace
