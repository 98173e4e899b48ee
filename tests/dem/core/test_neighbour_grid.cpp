// The neighbour grid's memory is bounded whatever the particles' spread (issue 34, item 3).

#include <catch2/catch.hpp>
#include <vector>

#include "dem_test_util.hpp"
#include "demfem/dem/dem_system.hpp"

using namespace demfem::dem;
using namespace demfem::dem::test;

TEST_CASE("A particle far from a bed of fine spheres does not blow up the cell grid",
          "[dem][detection]") {
  // 64 spheres of 0.1 mm radius in a block on a floor and one 450 m away on every axis: cells of about
  // 0.2 mm over 450 m are 2.2e6 per axis, 1.1e19 in all, which wrapped around in the int64
  // count, passed the bound and made the allocation fail (bad_alloc). Now the cells coarsen
  // until the grid has at most 4 n + 4096 of them, and the bed's contacts are still found.
  auto s = two_material_settings(1e8, 0.3, 2500.0, 0.4, 0.5, 1e-7);
  DemSystem sys(s);
  sys.add_wall(plane_mesh(0.01, 2));  // a floor under the block: its triangles are binned too
  std::vector<ParticleInit> p;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i)  // touching neighbours: 1.99e-4 m apart
        p.push_back(sphere({1.99e-4 * i, 1.99e-4 * j, 1e-4 + 1.99e-4 * k}, 1e-4));
  p.push_back(sphere({1000.0, 1000.0, 1000.0}, 1e-4));
  sys.add_particles(p);
  REQUIRE_NOTHROW(sys.advance(2));
  CHECK(sys.contact_count() == 3 * 4 * 4 * 3);  // the lattice's touching pairs
  CHECK(sys.particles().pz[64] == 1000.0);      // no gravity, nothing touches it
}
