// Layer descriptions and on_activate / on_deactivate hooks (the Python core's semantics).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "contextros/contextros.hpp"
#include "fixtures.hpp"

namespace {

class Hooks : public RuntimeTest {
 protected:
  void SetUp() override {
    RuntimeTest::SetUp();
    events.clear();
    for (const char* name : {"HookA", "HookB"}) {
      const std::string layer = name;
      contextros::define_layer({layer, {}, {}, {}, ""}, "the layer " + layer,
                               {[this, layer] { events.push_back(layer + " on"); },
                                [this, layer] { events.push_back(layer + " off"); }});
    }
  }
  Names events;
};

TEST_F(Hooks, DescriptionsAreKeptByName) {
  EXPECT_EQ(contextros::layer_description("HookA"), "the layer HookA");
  EXPECT_EQ(contextros::layer_description("NobodyDefinedThis"), "");
}

TEST_F(Hooks, DeactivateNewestFirstThenActivateInActivationOrder) {
  contextros::set_active({"HookA", "HookB"});
  EXPECT_EQ(events, (Names{"HookA on", "HookB on"}));
  events.clear();
  contextros::set_active({});
  EXPECT_EQ(events, (Names{"HookB off", "HookA off"}));
  events.clear();
  contextros::activate("HookA");
  contextros::activate("HookA");  // already active: no switch, no hook
  EXPECT_EQ(events, (Names{"HookA on"}));
}

TEST_F(Hooks, ADeactivateHookSeesTheOldConfigurationAndAnActivateHookTheNew) {
  Names seen;
  contextros::define_layer({"HookSeen", {}, {}, {}, ""}, "",
                           {[&] { seen = contextros::active_layers(); },
                            [&] { seen = contextros::active_layers(); }});
  contextros::activate("HookSeen");
  EXPECT_EQ(seen, (Names{"HookSeen"}));
  contextros::deactivate("HookSeen");
  EXPECT_EQ(seen, (Names{"HookSeen"}));  // still active while its on_deactivate runs
}

TEST_F(Hooks, AFailingDeactivateHookAbandonsTheSwitch) {
  contextros::define_layer({"HookStuck", {}, {}, {}, ""}, "",
                           {{}, [] { throw std::runtime_error("motor busy"); }});
  contextros::activate("HookStuck");
  const auto epoch = contextros::current_epoch();
  const auto outcome = contextros::deactivate("HookStuck");
  EXPECT_EQ(outcome.status, contextros::SwitchStatus::failed);
  EXPECT_EQ(outcome.error, "on_deactivate hook of layer HookStuck failed: motor busy");
  EXPECT_EQ(contextros::active_layers(), (Names{"HookStuck"}));
  EXPECT_EQ(contextros::current_epoch(), epoch);
  contextros::define_layer({"HookStuck", {}, {}, {}, ""});  // redefined without hooks
}

TEST_F(Hooks, AFailingActivateHookKeepsTheNewConfigurationAndSaysSo) {
  contextros::define_layer({"HookBroken", {}, {}, {}, ""}, "",
                           {[] { throw std::runtime_error("no lidar"); }, {}});
  const auto outcome = contextros::set_active({"HookBroken", "HookA"});
  EXPECT_EQ(outcome.status, contextros::SwitchStatus::applied);
  EXPECT_EQ(outcome.error, "on_activate hook of layer HookBroken failed: no lidar");
  EXPECT_EQ(contextros::active_layers(), (Names{"HookBroken", "HookA"}));
  EXPECT_EQ(events, (Names{"HookA on"}));  // the other hooks still ran
}

TEST_F(Hooks, DeferredSwitchesRunTheirHooksWhenTheyApply) {
  {
    contextros::CriticalSection section;
    contextros::activate("HookA");
    EXPECT_TRUE(events.empty());
  }
  EXPECT_EQ(events, (Names{"HookA on"}));
}

}  // namespace
