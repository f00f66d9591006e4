// Layered functions and methods, written the way generated code writes them.
#include <gtest/gtest.h>

#include <string>

#include "contextros/contextros.hpp"
#include "fixtures.hpp"

namespace {

// A free function with a base and three layers; each partial proceeds.
using Trace = contextros::ProceedOf<std::string(const std::string&)>;
std::string trace_base(Trace, const std::string& arg) { return "base(" + arg + ")"; }
std::string trace_A(Trace proceed, const std::string& arg) { return "A>" + proceed(arg); }
std::string trace_B(Trace proceed, const std::string& arg) { return "B>" + proceed(arg); }
std::string trace_C(Trace, const std::string& arg) { return "C:" + arg; }  // no proceed

contextros::LayeredOf<std::string(const std::string&)> trace_layered{
    "trace", &trace_base, {{"DispA", &trace_A}, {"DispB", &trace_B}, {"DispC", &trace_C}}};
std::string trace(const std::string& arg) { return trace_layered.invoke(nullptr, arg); }

// No base: a call needs an active partial.
using Pos = contextros::ProceedOf<int()>;
int pos_A(Pos) { return 1; }
int pos_B(Pos proceed) { return 10 + proceed(); }
contextros::LayeredOf<int()> pos_layered{"pos", nullptr, {{"DispA", &pos_A}, {"DispB", &pos_B}}};
int pos() { return pos_layered.invoke(nullptr); }

class Dispatch : public RuntimeTest {};

TEST_F(Dispatch, NoActiveLayerRunsTheBase) { EXPECT_EQ(trace("x"), "base(x)"); }

TEST_F(Dispatch, NewestActivatedIsOutermost) {
  contextros::activate("DispA");
  EXPECT_EQ(trace("x"), "A>base(x)");
  contextros::activate("DispB");
  EXPECT_EQ(trace("x"), "B>A>base(x)");
  contextros::set_active({"DispB", "DispA"});
  EXPECT_EQ(trace("x"), "A>B>base(x)");
  contextros::activate("DispC");
  EXPECT_EQ(trace("x"), "C:x");
  contextros::set_active({"DispC", "DispA"});
  EXPECT_EQ(trace("x"), "A>C:x");
}

TEST_F(Dispatch, LayersWithoutAPartialAreTransparent) {
  contextros::set_active({"DispA", "Unrelated"});
  EXPECT_EQ(trace("y"), "A>base(y)");
}

TEST_F(Dispatch, NoBaseNoLayerIsNoImplementation) {
  try {
    pos();
    FAIL() << "expected NoImplementationError";
  } catch (const contextros::NoImplementationError& error) {
    EXPECT_NE(std::string(error.what()).find("pos has no base implementation"), std::string::npos)
        << error.what();
  }
  contextros::activate("DispA");
  EXPECT_EQ(pos(), 1);
  contextros::activate("DispB");
  EXPECT_EQ(pos(), 11);
}

// proceed is a value: a helper the partial hands it to runs the next implementation.
using Helped = contextros::ProceedOf<std::string(const std::string&)>;
std::string helped_base(Helped, const std::string& arg) { return "base(" + arg + ")"; }
std::string helper(const Helped& proceed, const std::string& arg) { return "h>" + proceed(arg); }
std::string helped_A(Helped proceed, const std::string& arg) { return helper(proceed, arg); }
contextros::LayeredOf<std::string(const std::string&)> helped_layered{
    "helped", &helped_base, {{"DispA", &helped_A}}};

TEST_F(Dispatch, ProceedHandedToAHelperRunsTheNextImplementation) {
  contextros::activate("DispA");
  EXPECT_EQ(helped_layered.invoke(nullptr, "x"), "h>base(x)");
}

TEST_F(Dispatch, ProceedPastTheLastImplementationThrows) {
  contextros::activate("DispB");
  try {
    pos();
    FAIL() << "expected ProceedError";
  } catch (const contextros::ProceedError& error) {
    EXPECT_NE(std::string(error.what()).find("proceed() in pos of layer DispB"), std::string::npos)
        << error.what();
  }
}

// A layered method, as generated for `int Counter::add(int n) const` in layers.
class Counter {
 public:
  explicit Counter(int start) : start_(start) {}
  int add(int n) const;
  std::string name();

 private:
  CONTEXTROS_LAYERED_CLASS;
  int start_;
  std::string name_ = "counter";
};

struct CounterAddBase {
  using result = int;
};
struct CounterAddDouble {
  using result = int;
};
struct CounterNameLoud {
  using result = std::string;
};
using AddProceed = contextros::ProceedOf<decltype(&Counter::add)>;
using NameProceed = contextros::ProceedOf<decltype(&Counter::name)>;

template <>
int Counter::contextros_impl<CounterAddBase>(AddProceed, int n) const {
  return start_ + n;
}
template <>
int Counter::contextros_impl<CounterAddDouble>(AddProceed proceed, int n) const {
  return 2 * proceed(n) + start_;  // members of the object, and proceed without `this`
}
template <>
std::string Counter::contextros_impl<CounterNameLoud>(NameProceed) {
  name_ += "!";  // a non-const method changes its object
  return name_;
}

contextros::LayeredOf<decltype(&Counter::add)> counter_add{
    "Counter::add",
    &contextros::MethodThunk<CounterAddBase, decltype(&Counter::add)>::call,
    {{"DispA", &contextros::MethodThunk<CounterAddDouble, decltype(&Counter::add)>::call}}};
int Counter::add(int n) const { return counter_add.invoke(this, n); }

contextros::LayeredOf<decltype(&Counter::name)> counter_name{
    "Counter::name",
    nullptr,
    {{"DispB", &contextros::MethodThunk<CounterNameLoud, decltype(&Counter::name)>::call}}};
std::string Counter::name() { return counter_name.invoke(this); }

TEST_F(Dispatch, MethodsRunOnTheirObject) {
  const Counter one(1), five(5);
  EXPECT_EQ(one.add(2), 3);
  contextros::activate("DispA");
  EXPECT_EQ(one.add(2), 7);
  EXPECT_EQ(five.add(2), 19);
  Counter loud(0);
  EXPECT_THROW(loud.name(), contextros::NoImplementationError);
  contextros::activate("DispB");
  EXPECT_EQ(loud.name(), "counter!");
  EXPECT_EQ(loud.name(), "counter!!");
}

}  // namespace
