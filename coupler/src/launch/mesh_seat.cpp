#include "launch/mesh_seat.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "demfem/coupling/coupling_settings.hpp"
#include "demfem/dem/run/dem_run.hpp"
#include "demfem/dem/scene/dem_scene.hpp"
#include "demfem/dem/scene/particle_source.hpp"
#include "demfem/dem/sensors/packing.hpp"
#include "demfem/fem/fem_scene.hpp"

namespace demfem::coupling::launch {

std::string MeshSeat::override_text() const {
  char buf[64];
  std::snprintf(buf, sizeof buf, "fem.mesh.translate=[0, 0, %.17g]", dz);
  return buf;
}

std::optional<MeshSeat> resolve_mesh_seat(const scene::Document& doc, std::uint64_t seed) {
  const auto fem = doc.root().table("fem");
  const auto mesh = fem ? fem->table("mesh") : std::nullopt;
  const auto seat_table = mesh ? mesh->table("seat") : std::nullopt;
  if (!seat_table) return std::nullopt;
  const scene::Table& seat = *seat_table;
  if (mesh->has("translate"))
    mesh->fail("translate", "and [fem.mesh.seat] both place the mesh: give one of them (the seat "
                            "computes the translation from the prepared bed)");
  MeshSeat out;
  out.gap = seat.number("gap", scene::Range::closed(0.0, 1.0));
  const bool margin_given = seat.has("margin");
  if (margin_given) out.margin = seat.number("margin", scene::Range::closed(0.0, 10.0));
  seat.finish();

  const auto dem = doc.root().table("dem");
  const auto load = dem ? dem->table("load") : std::nullopt;
  if (names_external_backend(dem))
    seat.fail("gap", "[fem.mesh.seat] reads the prepared bed with demfem's own DEM: not with "
                     "dem.backend = \"external\" (give fem.mesh.translate instead)");
  if (!load)
    seat.fail("gap", "[fem.mesh.seat] places the mesh on a prepared bed: the scene needs the "
                     "[dem.load] that loads it");
  const dem::DemScene ds = dem::read_dem_scene(*dem);
  // --check before the prepare scene has made the state: the keys are checked, dz = 0.
  if (!ds.load->prepare_scene.empty() &&
      !dem::state_is_current(ds.load->file, ds.load->prepare_scene, ds.load->prepare_overrides))
    return out;

  // The mesh as the file gives it (the FEM reader moves it only by a translate, which the
  // seat is about to compute: zero here).
  std::vector<scene::Override> with_zero = doc.overrides();
  with_zero.push_back(scene::Override::parse("fem.mesh.translate=[0, 0, 0]"));
  const scene::Document unmoved = scene::Document::load(doc.file(), with_zero);
  const fem::FemScene fs = fem::read_fem_scene(*unmoved.root().table("fem"));
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<double, 3> lo{inf, inf, inf}, hi{-inf, -inf, -inf};
  for (const auto& x : fs.problem.mesh.nodes) {
    for (std::size_t k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], x[k]);
      hi[k] = std::max(hi[k], x[k]);
    }
  }
  out.mesh_bottom = lo[2];

  const auto bed = dem::DemRun::setup(ds, seed);
  const dem::ParticleState& p = bed->system().particles();
  if (!margin_given) {
    for (double r : p.radius) out.margin = std::max(out.margin, r);
  }
  // Every particle centre in z: the bed below the mesh is all that the state holds.
  const double z_span = 1e9;
  const dem::PackingResult under =
      dem::packing_in_box(bed->system(), {lo[0] - out.margin, lo[1] - out.margin, -z_span},
                          {hi[0] + out.margin, hi[1] + out.margin, z_span});
  out.particles = under.particles;
  if (under.particles == 0) {
    char what[256];
    std::snprintf(what, sizeof what,
                  "no particle of the prepared state lies under the mesh's footprint (x %g to "
                  "%g m, y %g to %g m, widened by %g m): the mesh is not over the bed",
                  lo[0], hi[0], lo[1], hi[1], out.margin);
    seat.fail("gap", what);
  }
  out.bed_top = under.top;
  out.computed = true;
  out.dz = out.bed_top + out.gap - out.mesh_bottom;
  return out;
}

}  // namespace demfem::coupling::launch
