// Layered functions: the dispatch machinery behind code generated from C++ layer files.
//
// A layered function has a base implementation (or none) and one partial implementation
// per layer that refines it. For every configuration the runtime composes the chain of
// implementations once (the most recently activated layer outermost, then the next older
// one, ..., then the base), caches it for that configuration and installs it with one
// atomic store. A free function's call is one atomic load and one indirect call of the
// head's code, as a plain atomic function pointer; the head's proceed() finds the chain
// installed with it. A method's call loads the head link, then its code (two dependent
// loads): its proceed carries the link and the object, two registers, as a free
// function's carries the link and the head's code (a third word would pass it through
// memory). While objects have layers of their own (activate_for), a method whose chain
// differs for some of them goes through their table: the calls on other objects take the
// decisive chain after one look-up, without the per-thread scoped path.
// Chains are immutable, so a call and all its proceed() calls run the implementations of
// one configuration, whatever another thread switches meanwhile.
// Composed chains are never freed before the layered function is (a running call may use
// them); there is one per distinct configuration seen, and one table of objects per
// distinct set of objects with layers of their own (and of their chains) seen.
//
// Generated code (contextros compile) declares one Layered object per function; see
// docs/language.md. Writing one by hand works too:
//
//   static double speed_Indoor(contextros::ProceedOf<double(double)> proceed, double f) {
//     return proceed(f) * 0.5;
//   }
//   static double speed_base(contextros::ProceedOf<double(double)>, double f) { return f; }
//   static contextros::LayeredOf<double(double)> speed_layered{
//       "speed", &speed_base, {{"Indoor", &speed_Indoor}}};
//   double speed(double f) { return speed_layered.invoke(nullptr, f); }
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "contextros/activation.hpp"
#include "contextros/errors.hpp"
#include "contextros/layer.hpp"

namespace contextros {

namespace detail {

// What the runtime knows of a layered function: a name, and how to rewire it.
class LayeredBase {
 public:
  explicit LayeredBase(std::string name) : name_(std::move(name)) {}
  virtual ~LayeredBase();
  LayeredBase(const LayeredBase&) = delete;
  LayeredBase& operator=(const LayeredBase&) = delete;

  const std::string& name() const noexcept { return name_; }

  // The objects with layers of their own (activate_for) and the configuration a call on
  // each runs (without scopes).
  using Levels = std::vector<std::pair<const void*, std::vector<std::string>>>;

  // Called by the runtime, its lock held: install the chain composed for `configuration`
  // (oldest first), or the scoped entry when `scoped` (threads with scoped activations);
  // for a method, the chains of the `receivers` too.
  virtual void rewire(const std::vector<std::string>& configuration, bool scoped,
                      const Levels& receivers) = 0;

 protected:
  // Registers with the runtime, which rewires the function at once. The last thing a
  // derived constructor does (the runtime may call rewire() from then on).
  void enroll();
  // Unregisters (waiting for a switch in progress). The first thing a derived destructor
  // does: no switch may rewire() a half-destroyed function.
  void unenroll() noexcept;

 private:
  std::string name_;
  bool enrolled_ = false;
};

// The scoped call path (taken while scoped activations, or objects with layers of their
// own, exist somewhere in the process): the head of `function`'s chain for the calling
// thread and `receiver` (the object of a method call, null for a free function). Without
// scopes in this thread and layers of the receiver's own, `decisive`; else the chain
// composed for that configuration, cached per thread, function and receiver until the
// configuration changes (composing takes the runtime lock).
using Compose = const void* (*)(const LayeredBase& function,
                                const std::vector<std::string>& configuration);
const void* scoped_head(const LayeredBase& function, const void* decisive, Compose compose,
                        const void* receiver);

[[noreturn]] void throw_no_implementation(const std::string& function, const void* receiver);
[[noreturn]] void throw_proceed_past_end(const std::string& function, const char* layer);

}  // namespace detail

template <class Self, class Signature>
class Layered;

// A layered function of signature R(Args...); Self is the class (const-qualified for a const
// method) for a layered method, void for a free function.
template <class Self, class R, class... Args>
class Layered<Self, R(Args...)> final : public detail::LayeredBase {
  static constexpr bool is_method = !std::is_void_v<Self>;

 public:
  class Proceed;
  // An implementation: a partial or the base. `proceed` runs the next one.
  using Impl = R (*)(Proceed proceed, Args... args);
  // What a proceed carries beside its link: the object of a method; for a free function,
  // the code of the head of the call (what head_proceed needs).
  using Carried = std::conditional_t<is_method, Self*, Impl>;

  struct Partial {
    std::string layer;
    Impl impl;
  };

  // One link of a composed chain.
  struct Node {
    Impl fn;
    const Node* next;
    const Layered* owner;
    const char* layer;  // the layer whose partial this is; "" for the base
  };

  // The next implementation of the running chain, and the object of a method. Two words:
  // passed in registers.
  class Proceed {
   public:
    R operator()(Args... args) const {
      const Node* next = node_->next;
      return next->fn(Proceed(next, carried_), std::forward<Args>(args)...);
    }
    // The object a layered method runs on.
    template <class S = Self, std::enable_if_t<!std::is_void_v<S>, int> = 0>
    S& self() const noexcept {
      return *carried_;
    }

   private:
    friend class Layered;
    Proceed(const Node* node, Carried carried) noexcept : node_(node), carried_(carried) {}
    // The running implementation's link; for the head of a free function's call, the entry.
    const Node* node_;
    Carried carried_;
  };

  // `base` may be null (no base: a call with no active partial throws
  // NoImplementationError). One partial per layer.
  Layered(std::string name, Impl base, std::initializer_list<Partial> partials)
      : detail::LayeredBase(std::move(name)),
        base_(base),
        partials_(partials),
        latest_(std::make_unique<std::atomic<const Node*>[]>(partials_.size() + 1)) {
    for (std::size_t i = 0; i <= partials_.size(); ++i) latest_[i].store(nullptr);
    enroll();
  }
  ~Layered() override { unenroll(); }
  Layered(const Layered&) = delete;
  Layered& operator=(const Layered&) = delete;

  // The call. A free function: one atomic load (the head's code) and one indirect call, as
  // a plain atomic function pointer; the head gets the entry as its link, so its proceed
  // goes through head_proceed, which finds the chain installed with that head. A method:
  // the head link, then its code (the chain is bound by the first load).
  R invoke(Self* self, Args... args) const {
    if constexpr (is_method) {
      const Node* head = head_link_.load(std::memory_order_acquire);
      return head->fn(Proceed(head, self), std::forward<Args>(args)...);
    } else {
      const Impl head = head_.load(std::memory_order_acquire);
      return head(Proceed(&entry_, head), std::forward<Args>(args)...);
    }
  }

  void rewire(const std::vector<std::string>& configuration, bool scoped,
              const Levels& receivers) override {
    const Node* chain = compose(configuration);
    decisive_.store(chain, std::memory_order_release);
    if constexpr (is_method) {
      const Node* head = scoped ? &scoped_link_ : chain;
      if (!scoped) {
        // The objects whose chain differs (their layers refine this method), by address.
        Table table;
        for (const auto& [receiver, layers] : receivers) {
          const Node* own = compose(layers);
          if (own != chain) table.emplace_back(reinterpret_cast<std::uintptr_t>(receiver), own);
        }
        if (!table.empty()) {
          std::sort(table.begin(), table.end());
          // Before the head is published: a call through the table finds it.
          table_.store(&*tables_.insert(std::move(table)).first, std::memory_order_release);
          head = &table_link_;
        }
      }
      head_link_.store(head, std::memory_order_release);
    } else {
      const std::size_t index = index_of(chain->fn);
      // Before the head is published: a call that loads the head finds its chain.
      if (index <= partials_.size()) latest_[index].store(chain, std::memory_order_release);
      head_.store(scoped ? &Layered::scoped_entry : chain->fn, std::memory_order_release);
    }
  }

 private:
  // The proceed of the head of a call: the decisive chain's rest, or, when a switch came
  // between the call's load of its head and this proceed, the rest of the chain installed
  // last with that head (a configuration active during the call: never a mix of two).
  // (A free function's only: a method's call starts at its chain's head link.)
  static R head_proceed(Proceed proceed, Args... args) {
    if constexpr (is_method) {
      return past_end(proceed, std::forward<Args>(args)...);
    } else {
      const Layered* self = proceed.node_->owner;
      const Node* chain = self->decisive_.load(std::memory_order_acquire);
      if (chain->fn != proceed.carried_) chain = self->latest(proceed.carried_);
      const Node* next = chain->next;
      return next->fn(Proceed(next, proceed.carried_), std::forward<Args>(args)...);
    }
  }

  // The chain installed last with `head` at its head.
  const Node* latest(Impl head) const {
    return latest_[index_of(head)].load(std::memory_order_acquire);
  }

  // The position of `impl` among the partials (then the base); past them for the runtime's
  // own entries.
  std::size_t index_of(Impl impl) const {
    for (std::size_t i = 0; i < partials_.size(); ++i) {
      if (partials_[i].impl == impl) return i;
    }
    return impl == base_ && base_ ? partials_.size() : partials_.size() + 1;
  }

  // The chain for `configuration` (oldest first), composed once and cached. Runtime lock held.
  const Node* compose(const std::vector<std::string>& configuration) const {
    std::vector<std::size_t> refining;
    for (auto layer = configuration.rbegin(); layer != configuration.rend(); ++layer) {
      for (std::size_t i = 0; i < partials_.size(); ++i) {
        if (partials_[i].layer == *layer) refining.push_back(i);
      }
    }
    auto found = chains_.find(refining);
    if (found != chains_.end()) return found->second.get();
    const std::size_t size = refining.size() + (base_ ? 1 : 0) + 1;
    auto nodes = std::make_unique<Node[]>(size);
    std::size_t at = 0;
    for (std::size_t index : refining) {
      nodes[at] = Node{partials_[index].impl, &nodes[at + 1], this, partials_[index].layer.c_str()};
      ++at;
    }
    if (base_) {
      nodes[at] = Node{base_, &nodes[at + 1], this, ""};
      ++at;
    }
    const char* last = at ? nodes[at - 1].layer : "";
    nodes[at] = Node{at ? &Layered::past_end : &Layered::no_implementation, nullptr, this, last};
    const Node* head = nodes.get();
    chains_.emplace(std::move(refining), std::move(nodes));
    return head;
  }

  // The object of a method's call; none for a free function.
  static const void* receiver(const Proceed& proceed) noexcept {
    if constexpr (is_method) {
      return proceed.carried_;
    } else {
      return nullptr;
    }
  }

  // What a call of the chain `head` carries: the object of a method, the head's code for a
  // free function.
  static Carried carried(const Node* head, const Proceed& proceed) noexcept {
    if constexpr (is_method) {
      return proceed.carried_;
    } else {
      return head->fn;
    }
  }

  // Installed while scoped activations exist: finds the chain for the calling thread and
  // the call's object.
  static R scoped_entry(Proceed proceed, Args... args) {
    const Layered* self = proceed.node_->owner;
    const Node* head = static_cast<const Node*>(
        detail::scoped_head(*self, self->decisive_.load(std::memory_order_acquire),
                            &Layered::compose_for, receiver(proceed)));
    return head->fn(Proceed(head, carried(head, proceed)), std::forward<Args>(args)...);
  }

  // A method's head while objects whose chain differs exist (and no scopes): the chain of
  // the call's object in their table, else the decisive chain.
  static R table_entry(Proceed proceed, Args... args) {
    const Layered* self = proceed.node_->owner;
    const Table& table = *self->table_.load(std::memory_order_acquire);
    const Node* head = self->decisive_.load(std::memory_order_acquire);
    const auto key = reinterpret_cast<std::uintptr_t>(receiver(proceed));
    const auto found =
        std::lower_bound(table.begin(), table.end(), typename Table::value_type{key, nullptr});
    if (found != table.end() && found->first == key) head = found->second;
    return head->fn(Proceed(head, proceed.carried_), std::forward<Args>(args)...);
  }

  static const void* compose_for(const detail::LayeredBase& function,
                                 const std::vector<std::string>& configuration) {
    return static_cast<const Layered&>(function).compose(configuration);
  }

  static R no_implementation(Proceed proceed, Args...) {
    detail::throw_no_implementation(proceed.node_->owner->name(), receiver(proceed));
  }

  static R past_end(Proceed proceed, Args...) {
    detail::throw_proceed_past_end(proceed.node_->owner->name(), proceed.node_->layer);
  }

  Impl base_;
  std::vector<Partial> partials_;
  // A free function: what the head of a call gets as its link (its next is head_proceed),
  // and the head's code.
  Node after_head_{&Layered::head_proceed, nullptr, this, ""};
  Node entry_{nullptr, &after_head_, this, ""};
  std::atomic<Impl> head_{nullptr};
  std::atomic<const Node*> decisive_{nullptr};
  // Per partial (then the base): the chain installed last with it at its head.
  std::unique_ptr<std::atomic<const Node*>[]> latest_;
  // Every chain ever composed, by the refining partials (newest first). Never shrinks.
  mutable std::map<std::vector<std::size_t>, std::unique_ptr<Node[]>> chains_;
  // A method: the head link of a call (a chain, or one of the two entries below), and the
  // objects whose chain differs from the decisive one, sorted by address.
  using Table = std::vector<std::pair<std::uintptr_t, const Node*>>;
  Node scoped_link_{&Layered::scoped_entry, nullptr, this, ""};
  Node table_link_{&Layered::table_entry, nullptr, this, ""};
  std::atomic<const Node*> head_link_{nullptr};
  std::atomic<const Table*> table_{nullptr};
  // Every table ever installed. Never shrinks (a running call may use one).
  std::set<Table> tables_;
};

// Traits from a function type or a pointer to member function.
template <class F>
struct LayeredTraits;

template <class R, class... Args>
struct LayeredTraits<R(Args...)> {
  using type = Layered<void, R(Args...)>;
  using result = R;
};
template <class R, class... Args>
struct LayeredTraits<R(Args...) noexcept> : LayeredTraits<R(Args...)> {};

#define CONTEXTROS_DETAIL_MEMBER_TRAITS(QUALIFIERS, SELF)                     \
  template <class R, class C, class... Args>                                  \
  struct LayeredTraits<R (C::*)(Args...) QUALIFIERS> {                        \
    using type = Layered<SELF, R(Args...)>;                                   \
    using result = R;                                                         \
  };                                                                          \
  template <class R, class C, class... Args>                                  \
  struct LayeredTraits<R (C::*)(Args...) QUALIFIERS noexcept>                 \
      : LayeredTraits<R (C::*)(Args...) QUALIFIERS> {};
CONTEXTROS_DETAIL_MEMBER_TRAITS(, C)
CONTEXTROS_DETAIL_MEMBER_TRAITS(const, const C)
#undef CONTEXTROS_DETAIL_MEMBER_TRAITS

// The Layered type for a function type (`decltype(getPos)`) or a member function pointer
// type (`decltype(&Robot::getPos)`), and the type of its `proceed`.
template <class F>
using LayeredOf = typename LayeredTraits<F>::type;
template <class F>
using ProceedOf = typename LayeredOf<F>::Proceed;
template <class F>
using ResultOf = typename LayeredTraits<F>::result;

// Calls the per-layer member implementations of a class (see CONTEXTROS_LAYERED_CLASS):
// `&MethodThunk<Tag, decltype(&Robot::getPos)>::call` is the implementation of a layer.
template <class Tag, class F>
struct MethodThunk;

template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...)> {
  using Proceed = typename Layered<C, R(Args...)>::Proceed;
  static R call(Proceed proceed, Args... args) {
    return proceed.self().template contextros_impl<Tag, Proceed, Args...>(
        proceed, std::forward<Args>(args)...);
  }
};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) const> {
  using Proceed = typename Layered<const C, R(Args...)>::Proceed;
  static R call(Proceed proceed, Args... args) {
    return proceed.self().template contextros_impl<Tag, Proceed, Args...>(
        proceed, std::forward<Args>(args)...);
  }
};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) noexcept> : MethodThunk<Tag, R (C::*)(Args...)> {};
template <class Tag, class R, class C, class... Args>
struct MethodThunk<Tag, R (C::*)(Args...) const noexcept>
    : MethodThunk<Tag, R (C::*)(Args...) const> {};

}  // namespace contextros

// Placed in the body of a class whose methods a layer file refines: declares the member
// templates that hold the per-layer implementations (explicit specialisations, one per layer
// and method, generated from the layer file) and lets the generated code reach them. It does
// not change the access of the members around it. The compiler adds it by itself to a class
// defined in the layer file's header part.
#define CONTEXTROS_LAYERED_CLASS                                            \
  template <class ContextrosTag, class... ContextrosArgs>                   \
  typename ContextrosTag::result contextros_impl(ContextrosArgs... args);   \
  template <class ContextrosTag, class... ContextrosArgs>                   \
  typename ContextrosTag::result contextros_impl(ContextrosArgs... args) const; \
  template <class, class>                                                   \
  friend struct ::contextros::MethodThunk
