// experiment: the document a spec file holds, whatever its syntax: a JSON tree (keys in the file's order)
// and the line of every key path ("quantity[1].target_tv"), from toml++'s source regions or located in
// JSON text. spec.cpp reads an ExperimentSpec from it; spec_toml.cpp and spec_json.cpp build it.
#pragma once

#include "experiment/spec.h"

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <string_view>

namespace microsim::experiment {

struct SpecTree {
  nlohmann::ordered_json root = nlohmann::ordered_json::object();
  std::map<std::string, int> lines;  // key path -> line (1-based)
  std::string source;

  // The line of `path`, or of its closest enclosing path that has one; 0 if none.
  int line_of(std::string_view path) const;
};

// "parent.key" / "key" when parent is "", and "parent[index]".
std::string child_path(std::string_view parent, std::string_view key);
std::string item_path(std::string_view parent, std::size_t index);

SpecTree toml_tree(std::string_view text, const std::string& source);  // throws SpecError
SpecTree json_tree(std::string_view text, const std::string& source);  // throws SpecError
ExperimentSpec read_spec(const SpecTree& tree);                         // throws SpecError

}  // namespace microsim::experiment
