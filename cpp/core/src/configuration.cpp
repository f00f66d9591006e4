#include "configuration.hpp"

#include <algorithm>
#include <map>
#include <set>

#include "contextros/errors.hpp"

namespace contextros::detail {
namespace {

bool contains(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

Configuration with(Configuration layers, const std::string& layer, const Definitions& definitions) {
  const std::string group = definitions(layer).group;
  if (!group.empty()) {
    layers.erase(std::remove_if(layers.begin(), layers.end(),
                                [&](const std::string& other) {
                                  return other != layer && definitions(other).group == group;
                                }),
                 layers.end());
  }
  if (!contains(layers, layer)) layers.push_back(layer);
  return layers;
}

}  // namespace

bool is_identifier(const std::string& name) {
  if (name.empty()) return false;
  auto letter = [](char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_'; };
  if (!letter(name[0])) return false;
  return std::all_of(name.begin(), name.end(),
                     [&](char c) { return letter(c) || (c >= '0' && c <= '9'); });
}

void validate(const Configuration& configuration, const Definitions& definitions) {
  std::set<std::string> active;
  std::set<std::string> repeated;
  for (const auto& name : configuration) {
    if (!active.insert(name).second) repeated.insert(name);
  }
  if (!repeated.empty()) {
    std::string names;
    for (const auto& name : repeated) names += (names.empty() ? "" : ", ") + name;
    throw RelationError("layer(s) " + names + " listed twice",
                        std::vector<std::string>(repeated.begin(), repeated.end()));
  }
  std::map<std::string, std::string> groups;
  for (const auto& name : configuration) {
    const LayerInfo definition = definitions(name);
    std::set<std::string> excludes(definition.excludes.begin(), definition.excludes.end());
    for (const auto& other : excludes) {
      if (active.count(other)) {
        throw RelationError("layers " + name + " and " + other + " cannot be active together (" +
                                name + " excludes " + other + ")",
                            {name, other});
      }
    }
    std::set<std::string> required(definition.required.begin(), definition.required.end());
    for (const auto& needed : required) {
      if (!active.count(needed)) {
        throw RelationError("layer " + name + " requires " + needed +
                                ", which would not be active (activate " + needed +
                                " too, or deactivate " + name + ")",
                            {name, needed});
      }
    }
    if (!definition.group.empty()) {
      auto [it, inserted] = groups.emplace(definition.group, name);
      if (!inserted) {
        throw RelationError("layers " + it->second + " and " + name +
                                " are both in exclusive group '" + definition.group + "'",
                            {it->second, name});
      }
    }
  }
}

Configuration plan(const Configuration& current, const std::vector<std::string>& activate,
                   const std::vector<std::string>& deactivate, const Definitions& definitions) {
  std::set<std::string> both;
  for (const auto& name : activate) {
    if (contains(deactivate, name)) both.insert(name);
  }
  if (!both.empty()) {
    std::string names;
    for (const auto& name : both) names += (names.empty() ? "" : ", ") + name;
    throw RelationError(
        "layer(s) " + names + " asked to be both activated and deactivated in one switch",
        std::vector<std::string>(both.begin(), both.end()));
  }
  std::map<std::string, std::string> requested;
  for (const auto& name : activate) {
    const std::string group = definitions(name).group;
    if (group.empty()) continue;
    auto [it, inserted] = requested.emplace(group, name);
    if (!inserted && it->second != name) {
      throw RelationError("layers " + it->second + " and " + name +
                              " are both in exclusive group '" + group +
                              "'; activate only one of them",
                          {it->second, name});
    }
  }
  Configuration layers;
  for (const auto& name : current) {
    if (!contains(deactivate, name)) layers.push_back(name);
  }
  for (const auto& name : activate) layers = with(std::move(layers), name, definitions);
  validate(layers, definitions);
  return layers;
}

Configuration replay(const Configuration& current, const std::vector<Step>& steps,
                     const Definitions& definitions) {
  Configuration layers = current;
  for (const auto& step : steps) {
    if (step.activating) {
      layers = with(std::move(layers), step.layer, definitions);
    } else {
      layers.erase(std::remove(layers.begin(), layers.end(), step.layer), layers.end());
    }
  }
  return layers;
}

}  // namespace contextros::detail
