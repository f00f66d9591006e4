// Pure rules for configurations (the Python core's configuration.py): which layers may be
// active together, and what a switch makes of the current configuration. No state.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "contextros/layer.hpp"

namespace contextros::detail {

using Configuration = std::vector<std::string>;  // activation order, last = outermost
// The current definition of a layer (a bare one for a name nobody defined).
using Definitions = std::function<LayerInfo(const std::string&)>;

struct Step {
  bool activating;
  std::string layer;
};

bool is_identifier(const std::string& name);
// Throws RelationError naming the layers when `configuration` breaks a relation.
void validate(const Configuration& configuration, const Definitions& definitions);
// The configuration after deactivating, then activating, the given layers (validated).
Configuration plan(const Configuration& current, const std::vector<std::string>& activate,
                   const std::vector<std::string>& deactivate, const Definitions& definitions);
// Scoped (de)activations applied to `current`, not validated.
Configuration replay(const Configuration& current, const std::vector<Step>& steps,
                     const Definitions& definitions);

}  // namespace contextros::detail
