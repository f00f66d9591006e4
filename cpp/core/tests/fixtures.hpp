// Shared by the runtime tests: a clean decisive configuration before each test.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "contextros/contextros.hpp"

class RuntimeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_FALSE(contextros::in_critical_section());
    ASSERT_EQ(contextros::set_active({}).status, contextros::SwitchStatus::applied);
  }
  void TearDown() override { contextros::set_active({}); }
};

using Names = std::vector<std::string>;
