// What a layered call is compared with: a plain out-of-line call, and the paper's
// Listing 2 dispatch (an if/else over the active layers on every call), extended with
// proceed. Defined in their own translation unit, like the generated dispatch functions.
#pragma once

namespace baseline {

int plain(int x);

// A plain member function, out of line (what a layered method is compared with).
struct Counter {
  int add(int x);
};

// The least any rewired dispatch can cost: one atomic load of a function pointer and an
// indirect call of it (no proceed, no chain; installed by set_active below).
int pointer_call(int x);

// The same, the callee taking a proceed (two pointers) before its argument, as a layered
// implementation does: what the argument registers' shuffle adds to the floor.
int pointer_call_with_proceed(int x);

// The layered call as it was before issue 18: two dependent loads (the head of the chain,
// then its function) and an indirect call, the head passed on for its proceed.
int two_loads_call(int x);

// Listing 2: which layers are active, tested on every call (newest first).
void set_active(bool l1, bool l2, bool l3);
int if_else_step(int x);    // partials proceed: L3 -> L2 -> L1 -> base
int if_else_single(int x);  // one partial that does not proceed

}  // namespace baseline
