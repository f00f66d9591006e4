// Layers as values: a name and its relations, registered process-wide.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace contextros {

// A layer as declared, with its relations (the same rules as the Python core's Layer).
struct LayerInfo {
  std::string name;
  std::vector<std::string> excludes;  // never active together with these (symmetric)
  std::vector<std::string> required;  // only active while these are ('requires' is a C++20 keyword)
  std::vector<std::string> after;     // when both are active, this one was activated later
  std::string group;                  // an exclusive group; "" = none
  std::vector<std::string> implies{};  // active whenever this one is: the manager brings them
};

bool operator==(const LayerInfo& a, const LayerInfo& b);
inline bool operator!=(const LayerInfo& a, const LayerInfo& b) { return !(a == b); }

// Whether `name` can name a layer or group: an identifier as Python's str.isidentifier()
// says (src/contextros/protocol/validation.py), in UTF-8. ASCII exactly; beyond ASCII, any
// well-formed code point except C1 controls and the Latin-1 signs and punctuation (no
// Unicode tables: other non-letters pass, the manager refuses them first).
bool is_layer_name(std::string_view name);

// Registers (or replaces: the latest definition of a name wins) a layer in this process.
// Throws LayerDefinitionError for an inconsistent declaration. Generated code calls this at
// static initialisation for every layer of its layer file.
void define_layer(const LayerInfo& layer);

// What a layer runs when a decisive switch turns it on or off (no arguments), as the Python
// core's on_activate / on_deactivate. On a switch: on_deactivate of each leaving layer
// (newest first, while it is still active), then the new configuration is installed, then
// on_activate of each arriving layer (in activation order). A throwing on_deactivate
// abandons the switch (outcome failed, nothing changed); a throwing on_activate leaves the
// new configuration in place (outcome applied, with the error). Run on the switching thread
// while switches are serialised, as observers are.
struct LayerHooks {
  std::function<void()> on_activate;
  std::function<void()> on_deactivate;
};

// define_layer with the layer's description (its documentation, "" for none) and hooks.
void define_layer(const LayerInfo& layer, std::string description, LayerHooks hooks = {});

// The description a layer was defined with ("" for none, or for a layer nobody defined).
std::string layer_description(std::string_view layer);

// Every layer defined in this process (the current definition of each name), by name.
std::vector<LayerInfo> defined_layers();

}  // namespace contextros
