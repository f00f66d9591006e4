// Code generated from a C++ layer file by contextros_add_layers (the fixture of the
// language's tests, tests/language/fixtures/cpp/robot.cpp.layers), run through the runtime.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

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

// Per-object activation (activate_for), on the generated methods of both fixtures.
// Objects are known by address: each test forgets its objects' layers when they go.
template <class T>
struct Forgotten {
  ~Forgotten() { contextros::reset_for(object); }
  const T& object;
};

TEST_F(Generated, ALayerActiveForOneObjectOnly) {
  Robot mine, other;
  Forgotten<Robot> forget{mine};
  contextros::activate_for(mine, "Indoor");
  EXPECT_EQ(mine.clean("hall"), "wipe+vacuum hall");
  EXPECT_EQ(other.clean("hall"), "vacuum hall");
  EXPECT_EQ(mine.getPos().x, 1.0);
  EXPECT_THROW(other.getPos(), contextros::NoImplementationError);
  EXPECT_DOUBLE_EQ(speed(), 1.0);  // a free function has no object: decisive layers only
  EXPECT_EQ(contextros::layers_for(mine), (Names{"Indoor"}));
  EXPECT_TRUE(contextros::active_layers().empty());
  std::string seen;
  std::thread([&] { seen = mine.clean("hall"); }).join();  // in every thread
  EXPECT_EQ(seen, "wipe+vacuum hall");
  contextros::reset_for(mine);
  EXPECT_EQ(mine.clean("hall"), "vacuum hall");
}

TEST_F(Generated, TheDocumentedOrderDecisiveThenObjectThenScope) {
  Robot mine, other;
  Forgotten<Robot> forget_mine{mine}, forget_other{other};
  contextros::activate("Indoor");
  contextros::activate_for(mine, "Night");
  contextros::deactivate_for(other, "Indoor");  // hides a decisive layer for that object
  EXPECT_EQ(mine.clean("hall"), "quietly wipe+vacuum hall by r1");
  EXPECT_EQ(other.clean("hall"), "vacuum hall");
  EXPECT_EQ(contextros::layers_for(mine), (Names{"Indoor", "Night"}));
  {
    contextros::ScopedDeactivation quiet_off("Night");  // the scope has the last word
    EXPECT_EQ(mine.clean("hall"), "wipe+vacuum hall");
    EXPECT_EQ(contextros::layers_for(mine), (Names{"Indoor"}));
  }
  EXPECT_EQ(mine.clean("hall"), "quietly wipe+vacuum hall by r1");
}

TEST_F(Generated, PerObjectActivationIsValidatedForTheObject) {
  Robot mine;
  Forgotten<Robot> forget{mine};
  try {
    contextros::activate_for(mine, "Docked");  // requires Indoor
    FAIL() << "expected RelationError";
  } catch (const contextros::RelationError& error) {
    EXPECT_NE(std::string(error.what()).find("requires Indoor"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("for this object"), std::string::npos);
  }
  EXPECT_TRUE(contextros::layers_for(mine).empty());  // nothing changed
  EXPECT_EQ(mine.clean("hall"), "vacuum hall");
}

TEST_F(Generated, ADecisiveSwitchThatConflictsSuspendsTheObjectsLayers) {
  Robot mine;
  Forgotten<Robot> forget{mine};
  contextros::activate_for(mine, "Indoor", "Night");
  EXPECT_EQ(mine.clean("hall"), "quietly wipe+vacuum hall by r1");
  // Docked excludes Night: never refused because of an object; mine's level is suspended.
  ASSERT_EQ(contextros::set_active({"Indoor", "Docked"}).status, contextros::SwitchStatus::applied);
  EXPECT_THROW(mine.clean("hall"), std::runtime_error);  // docked, as the process
  EXPECT_EQ(contextros::layers_for(mine), (Names{"Indoor", "Docked"}));
  EXPECT_THROW(contextros::activate_for(mine, "Outdoor"), contextros::RelationError);
  contextros::set_active({"Indoor"});  // the conflict is gone: the level applies again
  EXPECT_EQ(mine.clean("hall"), "quietly wipe+vacuum hall by r1");
}

// Issue 26: a proceed is two words for a method as for a free function, so the System V ABI
// passes it in registers (a third word, the object, passed it through memory: 4x slower).
TEST_F(Generated, AProceedIsTwoWordsPassedInRegisters) {
  using MethodProceed = contextros::ProceedOf<decltype(&Robot::clean)>;
  using FunctionProceed = contextros::ProceedOf<decltype(speed)>;
  EXPECT_EQ(sizeof(MethodProceed), 2 * sizeof(void*));
  EXPECT_EQ(sizeof(FunctionProceed), 2 * sizeof(void*));
  EXPECT_TRUE(std::is_trivially_copyable_v<MethodProceed>);
  EXPECT_TRUE(std::is_trivially_copyable_v<FunctionProceed>);
}

// Objects with layers of their own are found by address in a sorted table (many of them:
// a binary search); every other object takes the decisive chain.
TEST_F(Generated, ManyObjectsWithLayersOfTheirOwnEachRunTheirOwnChain) {
  std::vector<Robot> robots(24);
  std::vector<Forgotten<Robot>> forget;
  for (const auto& robot : robots) forget.push_back({robot});
  contextros::activate("Indoor");
  for (std::size_t i = 0; i < robots.size(); i += 3) contextros::activate_for(robots[i], "Night");
  for (std::size_t i = 1; i < robots.size(); i += 3) contextros::deactivate_for(robots[i], "Indoor");
  auto expect = [&](const char* night, const char* hidden, const char* decisive) {
    for (std::size_t i = 0; i < robots.size(); ++i) {
      EXPECT_EQ(robots[i].clean("hall"), i % 3 == 0 ? night : i % 3 == 1 ? hidden : decisive)
          << "robot " << i;
    }
  };
  expect("quietly wipe+vacuum hall by r1", "vacuum hall", "wipe+vacuum hall");
  contextros::set_active({});  // a decisive switch renews every object's chain
  expect("quietly vacuum hall by r1", "vacuum hall", "vacuum hall");
  for (std::size_t i = 0; i < robots.size(); i += 6) contextros::reset_for(robots[i]);
  for (std::size_t i = 0; i < robots.size(); i += 3) {
    EXPECT_EQ(robots[i].clean("hall"), i % 6 == 0 ? "vacuum hall" : "quietly vacuum hall by r1");
  }
}

// A call on an object runs the chain of one configuration while another thread changes the
// object's own layers and the decisive ones (tables are replaced, never changed in place).
TEST_F(Generated, MethodCallsNeverSeeAMixedChainWhileObjectsGainAndLoseLayers) {
  Robot mine, other;
  Forgotten<Robot> forget_mine{mine}, forget_other{other};
  const std::set<std::string> valid_mine = {"vacuum hall", "wipe+vacuum hall",
                                            "quietly vacuum hall by r1",
                                            "quietly wipe+vacuum hall by r1"};
  const std::set<std::string> valid_other = {"vacuum hall", "wipe+vacuum hall"};
  std::atomic<bool> stop{false};
  std::atomic<long> calls{0};
  std::vector<std::string> bad;
  std::thread caller([&] {
    while (!stop.load()) {
      const std::string seen_mine = mine.clean("hall");
      const std::string seen_other = other.clean("hall");
      calls.fetch_add(1);
      if (!valid_mine.count(seen_mine)) bad.push_back(seen_mine);
      if (!valid_other.count(seen_other)) bad.push_back(seen_other);
    }
  });
  while (calls.load() < 100) std::this_thread::yield();
  for (int round = 0; round < 2000; ++round) {
    contextros::set_active(round % 2 ? Names{"Indoor"} : Names{});
    if (round % 3 == 0) {
      contextros::activate_for(mine, "Night");
    } else {
      contextros::reset_for(mine);
    }
  }
  stop.store(true);
  caller.join();
  EXPECT_TRUE(bad.empty()) << bad.size() << " wrong results, e.g. " << (bad.empty() ? "" : bad[0]);
}

TEST_F(Generated, GuardsApplyToPerObjectActivation) {
  Cleaner mine, other;
  Forgotten<Cleaner> forget{mine};
  contextros::activate_for(mine, "GuardBig");
  EXPECT_EQ(mine.clean(30), "big base 30");
  EXPECT_EQ(mine.clean(1), "base 1");
  EXPECT_EQ(other.clean(30), "base 30");
}

}  // namespace
