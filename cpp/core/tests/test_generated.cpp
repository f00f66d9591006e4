// Code generated from a C++ layer file by contextros_add_layers (the fixture of the
// language's tests, tests/language/fixtures/cpp/robot.cpp.layers), run through the runtime.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <thread>

#include "contextros/contextros.hpp"
#include "fixtures.hpp"
#include "guards.layers.hpp"
#include "robot.layers.hpp"

namespace {

class Generated : public RuntimeTest {};

TEST_F(Generated, LayersAndRelationsAreDefinedAtStaticInitialisation) {
  Names names;
  for (const auto& layer : contextros::defined_layers()) {
    if (layer.name == "Docked") {
      EXPECT_EQ(layer.excludes, (Names{"Outdoor", "Night"}));
      EXPECT_EQ(layer.required, (Names{"Indoor"}));
      EXPECT_EQ(layer.after, (Names{"Indoor"}));
    }
    if (layer.name == "Indoor" || layer.name == "Outdoor") {
      EXPECT_EQ(layer.group, "place");
    }
    names.push_back(layer.name);
  }
  for (const char* name : {"Docked", "Indoor", "Night", "Outdoor"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  }
}

TEST_F(Generated, FreeFunctionsComposeNewestFirst) {
  EXPECT_DOUBLE_EQ(speed(), 1.0);  // the base, with the default argument
  contextros::activate("Indoor");
  EXPECT_DOUBLE_EQ(speed(2.0), 1.0);
  contextros::activate("Night");
  EXPECT_DOUBLE_EQ(speed(2.0), 0.25);
  contextros::activate("Outdoor");  // replaces Indoor (group); Night stays outermost
  EXPECT_EQ(contextros::active_layers(), (Names{"Night", "Outdoor"}));
  EXPECT_DOUBLE_EQ(speed(2.0), 4.0);
}

TEST_F(Generated, MethodsRunOnTheirObjectAndProceed) {
  Robot robot;
  EXPECT_THROW(robot.getPos(), contextros::NoImplementationError);
  EXPECT_EQ(robot.clean("hall"), "vacuum hall");
  contextros::set_active({"Indoor", "Night"});
  EXPECT_EQ(robot.getPos().x, 1.0);
  robot.name = "r2";
  EXPECT_EQ(robot.clean("hall"), "quietly wipe+vacuum hall by r2");
  EXPECT_EQ(contextros::set_active({"Indoor", "Night", "Docked"}).status,
            contextros::SwitchStatus::failed);
  contextros::set_active({"Indoor", "Docked"});
  EXPECT_THROW(robot.clean("hall"), std::runtime_error);
}

TEST_F(Generated, ScopedActivationOfGeneratedLayersIsPerThread) {
  Robot robot;
  std::string other;
  contextros::ScopedActivation outdoor("Outdoor");
  std::thread([&] { other = std::to_string(speed()); }).join();
  EXPECT_DOUBLE_EQ(speed(), 2.0);
  EXPECT_EQ(other, std::to_string(1.0));
  EXPECT_EQ(robot.getPos().y, 139.69);
}

// guards.cpp.layers: the Python flavour's tests/core/test_guards.py, in C++.
TEST_F(Generated, AGuardedPartialAppliesOnlyWhileItsConditionHolds) {
  Cleaner cleaner;
  {
    contextros::ScopedActivation big("GuardBig");
    EXPECT_EQ(cleaner.clean(20), "big base 20");
    EXPECT_EQ(cleaner.clean(5), "base 5");  // skipped: the call goes on to the base
  }
  contextros::activate("GuardBig");
  EXPECT_EQ(cleaner.clean(11), "big base 11");
  EXPECT_EQ(cleaner.clean(3), "base 3");
}

TEST_F(Generated, GuardsComposeWithProceedInActivationOrder) {
  Cleaner cleaner;
  contextros::set_active({"GuardBig", "GuardWet"});  // GuardWet newest: outermost
  EXPECT_EQ(cleaner.clean(20), "wet big base 20");
  EXPECT_EQ(cleaner.clean(12), "wet big base 12");
  EXPECT_EQ(cleaner.clean(13), "big base 13");  // GuardWet's guard false: straight to GuardBig
  EXPECT_EQ(cleaner.clean(4), "wet base 4");    // GuardBig's false: GuardWet proceeds to the base
  EXPECT_EQ(cleaner.clean(3), "base 3");
  EXPECT_EQ(reach(-4), 40);  // a guarded free function
  EXPECT_EQ(reach(4), 4);
}

TEST_F(Generated, HooksAndDescriptionsFromTheLayerFile) {
  guard_events.clear();
  EXPECT_EQ(contextros::layer_description("GuardBig"), "Large areas: the big brush.");
  EXPECT_EQ(contextros::layer_description("GuardWet"), "");
  contextros::set_active({"GuardBig", "GuardWet"});
  contextros::set_active({});
  EXPECT_EQ(guard_events, (Names{"GuardBig on", "GuardWet off", "GuardBig off"}));
}

}  // namespace
