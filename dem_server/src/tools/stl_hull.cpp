// hull_of_stl (declared with the shape library in shapes/mesh_hull.hpp): here, beside the STL
// reader, because demfem::dem links the shape library and not the other way round.

#include "demfem/dem/shapes/mesh_hull.hpp"
#include "demfem/dem/stl_reader.hpp"

namespace demfem::dem::shapes {

MeshHull hull_of_stl(const std::filesystem::path& file) {
  const WallMesh mesh = read_stl(file);
  return hull_of_closed_mesh(mesh.vertices, mesh.triangles, file.string());
}

}  // namespace demfem::dem::shapes
