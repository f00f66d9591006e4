#include "baselines.hpp"

#include <atomic>

namespace baseline {
namespace {

// The active layers, as Listing 2's `layer` variable: read by every call, written by a switch.
std::atomic<bool> active_l1{false}, active_l2{false}, active_l3{false};

int from(int level, int x);
int step_l3(int x) { return from(1, x) + 1; }
int step_l2(int x) { return from(2, x) + 1; }
int step_l1(int x) { return from(3, x) + 1; }

// The chain from `level` on: each partial's proceed re-enters the if/else below its layer.
int from(int level, int x) {
  if (level <= 0 && active_l3.load(std::memory_order_relaxed)) {
    return step_l3(x);
  } else if (level <= 1 && active_l2.load(std::memory_order_relaxed)) {
    return step_l2(x);
  } else if (level <= 2 && active_l1.load(std::memory_order_relaxed)) {
    return step_l1(x);
  }
  return x + 1;
}

int single_l1(int x) { return x + 2; }
int single_base(int x) { return x + 1; }

std::atomic<int (*)(int)> pointer{&single_base};

struct Anchor {
  const void* owner;
};
using WithProceed = int (*)(const Anchor* node, const void* head, int x);
int proceeding_l1(const Anchor*, const void*, int x) { return x + 2; }
int proceeding_base(const Anchor*, const void*, int x) { return x + 1; }
const Anchor anchor{nullptr};
std::atomic<WithProceed> pointer_proceed{&proceeding_base};

// The chain links of the layered call before issue 18: its head was a pointer to a link.
struct Node {
  int (*fn)(const Node* node, int x);
  const Node* next;
};
int node_l1(const Node*, int x) { return x + 2; }
int node_base(const Node*, int x) { return x + 1; }
const Node l1_chain{&node_l1, nullptr};
const Node base_chain{&node_base, nullptr};
std::atomic<const Node*> head{&base_chain};

}  // namespace

int plain(int x) { return x + 1; }

int Counter::add(int x) { return x + 1; }

int pointer_call(int x) { return pointer.load(std::memory_order_acquire)(x); }

int pointer_call_with_proceed(int x) {
  const WithProceed head = pointer_proceed.load(std::memory_order_acquire);
  return head(&anchor, reinterpret_cast<const void*>(head), x);
}

int two_loads_call(int x) {
  const Node* node = head.load(std::memory_order_acquire);
  return node->fn(node, x);
}

void set_active(bool l1, bool l2, bool l3) {
  pointer = l1 ? &single_l1 : &single_base;
  head = l1 ? &l1_chain : &base_chain;
  pointer_proceed = l1 ? &proceeding_l1 : &proceeding_base;
  active_l1 = l1;
  active_l2 = l2;
  active_l3 = l3;
}

int if_else_step(int x) { return from(0, x); }

int if_else_single(int x) {
  if (active_l1.load(std::memory_order_relaxed)) {
    return single_l1(x);
  }
  return single_base(x);
}

}  // namespace baseline
