// Names of nodes and elements for messages, and the mesh's orphan nodes (fem_problem.hpp).
#include <string>

#include "demfem/fem/fem_problem.hpp"

namespace demfem::fem {

namespace {

std::string named(const char* what, std::size_t i, const std::vector<std::int64_t>& labels,
                  const std::vector<SourceLine>& sources, const Mesh& m) {
  std::string s = what;
  s += ' ';
  const SourceLine* src = i < sources.size() ? &sources[i] : nullptr;
  if (src && src->instance >= 0 &&
      static_cast<std::size_t>(src->instance) < m.instance_names.size())
    s += m.instance_names[static_cast<std::size_t>(src->instance)] + ".";
  s += std::to_string(i < labels.size() ? labels[i] : static_cast<std::int64_t>(i + 1));
  if (src && src->file >= 0 && static_cast<std::size_t>(src->file) < m.source_files.size())
    s += " (" + m.source_files[static_cast<std::size_t>(src->file)] + ":" +
         std::to_string(src->line) + ")";
  return s;
}

}  // namespace

const char* formulation_name(SolidFormulation f) {
  return f == SolidFormulation::incompatible_modes ? "incompatible modes" : "B-bar";
}

std::string node_name(const Mesh& mesh, std::size_t node) {
  return named("node", node, mesh.node_labels, mesh.node_sources, mesh);
}

std::string element_name(const Mesh& mesh, std::size_t element) {
  return named("element", element, mesh.element_labels, mesh.element_sources, mesh);
}

std::vector<std::int32_t> orphan_nodes(const Mesh& mesh) {
  std::vector<char> used(mesh.nodes.size(), 0);
  for (const auto& el : mesh.elements)
    for (int a = 0; a < nodes_per_element(el.type); ++a) {
      const auto n = el.nodes[static_cast<std::size_t>(a)];
      if (n >= 0 && static_cast<std::size_t>(n) < used.size())
        used[static_cast<std::size_t>(n)] = 1;
    }
  std::vector<std::int32_t> out;
  for (std::size_t n = 0; n < used.size(); ++n)
    if (!used[n]) out.push_back(static_cast<std::int32_t>(n));
  return out;
}

}  // namespace demfem::fem
