#pragma once
// Particle shapes for dilated convex polyhedra (thesis §2.1.1, eq. 2.4-2.5): the host-side
// shape library (demfem::dem_shapes; host code with Eigen and Qhull, never compiled by nvcc).
// It stands on the geometry base in geometry/ (triangle meshes and the STL reader, the
// portable random stream, particle size distributions) and on nothing else of the DEM.
// Units SI. Namespace demfem::dem::shapes. Every error is a ShapeError whose what() names the
// input (file, generator and seed, or the caller's label) and the accepted range.
//
// API summary (details in each header):
//
//   convex_polyhedron.hpp  ConvexPolyhedron: the core. vertices() (body frame), triangles()
//       (counter-clockwise seen from outside), normals() (unit, outward), edges() (a < b with
//       the triangles left/right of a -> b and the exterior angle, 0 inside a merged facet),
//       neighbours(v) / vertex_triangles(v) (the fan around v, counter-clockwise seen from
//       outside), support(d), width(d). Always valid: closed, convex, non-degenerate; or the point
//       core (1 vertex, 0 triangles, 0 edges; is_point()), whose dilation is a sphere.
//       ConvexPolyhedron::hull(points, source)          Qhull "Qt"
//       ConvexPolyhedron::from_triangles(v, t, source)  a given triangulation, checked
//       ConvexPolyhedron::point(p)
//       make_box, make_cube, make_regular_tetrahedron, make_octahedron,
//       make_triangular_prism                           simple solids for tests
//   mass_properties.hpp    core_mass_properties(k), dilated_mass_properties(k, r): volume,
//       centroid, inertia tensor about the centroid per unit density, exact (core, face
//       slabs, edge wedges, vertex sectors); steiner_coefficients(k); principal_frame(I).
//   sieve_size.hpp         sieve_size(k): the smallest square aperture (core; + 2 r_d dilated).
//   particle_shape.hpp     ParticleShape: core in the dilated body's principal frame with the
//       dilated centroid at the origin, dilation_radius, volume, principal_moments (per unit
//       density, ascending, about body x, y, z), bounding_radius (max |vertex| + r_d),
//       sieve_size, volume_equivalent_diameter, extents, elongation, flatness.
//       make_particle_shape(core, size, SizeKind::{sieve, volume_equivalent}, r_d fraction,
//       source): the core shrunk so that core + r_d has the size; describe_dilated(core, r_d):
//       as is; scale(shape, s): exact similarity.
//   random_rock.hpp        random_rock(RockParams{triangles, elongation, flatness}, seed):
//       exactly `triangles` (even, >= 4) triangles, extents 1, e, e f along x, y, z.
//   mesh_hull.hpp          hull_of_closed_mesh(vertices, triangles, source),
//       hull_of_stl(file): the hull of a closed STL, with a warning when the mesh is not
//       convex.
//   shape_library.hpp      ShapeLibrary: K unit shapes (size 1 m); scaled(k, size) gives a
//       particle's r_d, volume, moments and bounding radius without geometry (exact scaling);
//       sample(rng, SizeDistribution) draws shape and size independently.
//
// Proposed use by the dynamics (scene keys are the scene's business; this is a sketch):
//
//   using namespace demfem::dem::shapes;
//   auto lib = ShapeLibrary::random_rocks({.triangles = 30, .elongation = 0.8,
//                                          .flatness = 0.7}, 500, seed, SizeKind::sieve, 0.1);
//   Rng rng(seed);
//   const auto dist = SizeDistribution::normal(0.04, 0.01, 0.02, 0.08);
//   for (each particle) {
//     const ScaledShape s = lib.sample(rng, dist);
//     mass = rho * s.volume;  inertia = rho * s.principal_moments (body frame);
//     r_d = s.dilation_radius;  broad-phase radius = s.bounding_radius;
//     core vertices (body frame) = s.scale * lib.unit(s.shape).core.vertices();
//     orientation: a random rotation (body -> world); position: the centroid.
//   }
//   Device side: upload each unit core once (vertices, triangles, edges, fans) and keep
//   per particle {shape index, scale}; a support point is scale * unit support.

#include "demfem/dem/shapes/convex_polyhedron.hpp"
#include "demfem/dem/shapes/mass_properties.hpp"
#include "demfem/dem/shapes/mesh_hull.hpp"
#include "demfem/dem/shapes/particle_shape.hpp"
#include "demfem/dem/shapes/random_rock.hpp"
#include "demfem/dem/shapes/shape_library.hpp"
#include "demfem/dem/shapes/sieve_size.hpp"
