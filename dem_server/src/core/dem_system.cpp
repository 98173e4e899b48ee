// DemSystem: state, contact detection, walls and the CPU (OpenMP) backend. The physics
// (contact law, integrator, triangle geometry) comes from include/demfem/dem/physics/*.hpp,
// shared with the CUDA backend (cuda/*.cu).
//
// Step structure (velocity Verlet, see physics/integrator.hpp):
//   1. per particle: half kick with the last force, drift, max displacement since the last
//      list update
//   2. walls: vertex positions/velocities at the new time (moving walls, flexible mesh)
//   3. pair list: refiltered from the grid build's candidates when the two largest
//      displacements since the last update may have closed the list skin, built from the
//      grid when the candidates may no longer hold every pair that can touch (two levels,
//      see Impl::orow and step())
//   4. per particle i (parallel): forces of the pairs (i, j > i) of its CSR row, written to
//      per-pair slots
//   5. per particle (parallel): own-row slots + transposed pair slots (fixed order) + walls +
//      gravity, second half kick
//   6. walls (serial, fixed order, at the last substep of an advance() or for averaged
//      flexible node forces): per-wall force/torque and flexible node forces
// No floating-point atomics: every sum has a fixed order independent of the thread count, so
// the result is bitwise identical for any number of threads.

#include "demfem/dem/dem_system.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "dem_cuda_backend.hpp"
#include "demfem/dem/physics/contact.hpp"
#include "demfem/dem/physics/geometry.hpp"
#include "demfem/dem/physics/integrator.hpp"
#include "demfem/dem/physics/pair.hpp"
#include "demfem/dem/physics/rigid_body.hpp"
#include "demfem/dem/physics/wall_contact.hpp"
#include "demfem/dem/physics/wall_motion.hpp"
#include "demfem/io/h5_file.hpp"
#include "multiversion.hpp"
#include "polyhedra.hpp"
#include "rigid_mesh_bodies.hpp"
#include "shape_table.hpp"

namespace demfem::dem {

using phys::Vec3;

namespace {

constexpr int kMaxWallContacts = phys::kMaxWallContacts;

[[noreturn]] void bad(const std::string& what) {
  throw std::invalid_argument("DemSystem: " + what);
}

bool finite3(const std::array<double, 3>& a) {
  return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]);
}

void validate(const DemSettings& s) {
  if (!(s.dt > 0.0) || !std::isfinite(s.dt))
    bad("settings.dt = " + std::to_string(s.dt) + " must be finite and > 0 s");
  if (!finite3(s.gravity)) bad("settings.gravity must be finite");
  if (s.materials.empty()) bad("settings.materials is empty (need at least one material)");
  const std::size_t n = s.materials.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& m = s.materials[i];
    const std::string where = "settings.materials[" + std::to_string(i) + "] ('" + m.name + "')";
    if (!(m.youngs_modulus > 0.0) || !std::isfinite(m.youngs_modulus))
      bad(where + ".youngs_modulus = " + std::to_string(m.youngs_modulus) + " must be > 0 Pa");
    if (!(m.poisson_ratio >= 0.0 && m.poisson_ratio < 0.5))
      bad(where + ".poisson_ratio = " + std::to_string(m.poisson_ratio) + " outside [0, 0.5)");
    if (!(m.density >= 0.0) || !std::isfinite(m.density))
      bad(where + ".density = " + std::to_string(m.density) + " must be >= 0 kg/m^3");
  }
  if (s.pairs.size() != n * n)
    bad("settings.pairs has " + std::to_string(s.pairs.size()) +
        " entries, need materials^2 = " + std::to_string(n * n));
  for (std::size_t k = 0; k < s.pairs.size(); ++k) {
    const auto& p = s.pairs[k];
    const std::string where = "settings.pairs[" + std::to_string(k) + "]";
    if (!(p.restitution > 0.0 && p.restitution <= 1.0))
      bad(where + ".restitution = " + std::to_string(p.restitution) + " outside (0, 1]");
    if (!(p.friction >= 0.0) || !std::isfinite(p.friction))
      bad(where + ".friction = " + std::to_string(p.friction) + " must be >= 0");
    if (!(p.rolling_friction >= 0.0) || !std::isfinite(p.rolling_friction))
      bad(where + ".rolling_friction = " + std::to_string(p.rolling_friction) + " must be >= 0");
    if (!(p.rocking_damping >= 0.0 && p.rocking_damping <= 10.0))
      bad(where + ".rocking_damping = " + std::to_string(p.rocking_damping) +
          " must be in [0, 10]");
  }
  if (!(s.list_skin >= 0.0 && s.list_skin <= 1.0))
    bad("settings.list_skin = " + std::to_string(s.list_skin) +
        " must be in [0, 1] (fraction of the skin; 0 = adaptive)");
  if (!(s.skin >= 0.0) || !std::isfinite(s.skin))
    bad("settings.skin = " + std::to_string(s.skin) + " must be >= 0 m");
  if (s.backend != "cpu" && s.backend != "cuda")
    bad("settings.backend = '" + s.backend + "', accepted: 'cpu', 'cuda'");
  if (s.threads < 0) bad("settings.threads = " + std::to_string(s.threads) + " must be >= 0");
}

// POD copy of a wall's motion for the shared kinematics (physics/wall_motion.hpp).
phys::RigidMotion rigid_motion(const WallMotion& m) {
  phys::RigidMotion r{};
  r.kind = static_cast<int>(m.kind);
  for (int d = 0; d < 3; ++d)
    r.velocity[d] = m.velocity[d], r.axis_point[d] = m.axis_point[d], r.axis[d] = m.axis[d];
  r.angular_velocity = m.angular_velocity, r.amplitude = m.amplitude;
  r.frequency = m.frequency, r.phase = m.phase;
  r.start_time = m.start_time, r.end_time = m.end_time;
  return r;
}

}  // namespace

namespace {

// Skin of the pair list as a fraction of the build skin (see DemSystem::Impl::orow), and its
// range when it adapts. On the settled 20,000-sphere bed (dem_throughput) 0.1 keeps 2.6 list
// pairs per particle (the whole skin: 3.6) and refilters every ~25 steps: +15 % particle-steps
// per second (best of 8 runs; 0.05: 2.5 pairs, no further gain). In a fast flow a thin
// skin would refilter every step or two, so the skin grows there (Impl::adapt_inner_skin()).
constexpr double kInnerSkin = 0.1, kInnerSkinMax = 0.5;

// The wall contacts of one particle, not inlined into the gather: most particles have none,
// and inlined, their code (a 1.6 kB stack frame, many live values) made the gather's slot
// sums spill and every particle pay its prologue.
template <bool Friction>
[[gnu::noinline]] void wall_contacts_apart(const phys::ParticleView& p, const phys::WallView& w,
                                           std::int64_t i, const phys::PairConstants* pc_row,
                                           double dt, Vec3& f, Vec3& q, double& mo, double& fmo) {
  phys::wall_contacts<Friction>(p, w, i, pc_row, dt, f, q, mo, fmo);
}

// ---------------------------------------------------------------------------------------
// Pair forces over a range of the flat pair list, one pair per SIMD lane: the contact law
// (physics/pair.hpp, contact.hpp) has no data-dependent branch, so the loop vectorises.
// On x86-64 (GCC/Clang, not under nvcc) the loop is compiled for the baseline (SSE2), for
// AVX2 and, with GCC, for x86-64-v4 (AVX-512: 32 vector registers, so the long law spills
// less; measured 7-12 % faster than AVX2 on a Xeon with both), and the loader picks the clone
// the CPU supports. Without FMA contraction every clone rounds each operation as the scalar
// code does (IEEE +, -, *, /, sqrt), so the clones give bitwise identical results (checked:
// a build without clones gives the same bits).
struct PairKernelArgs {
  phys::ParticleView view;
  const std::int32_t* pi;  // i of each pair
  const std::int32_t* pj;  // j of each pair
  const std::int32_t* mat;
  const phys::PairConstants* pc;  // table (nmat x nmat) or, when uniform, the one entry
  std::size_t nmat;
  double dt;
  double* shear;  // 3 per pair
  double* pf;     // 3 per pair
  double* pt;     // 3 per pair (Friction)
  double* pr;     // 3 per pair (Rolling)
  double* rhist;  // 3 per pair (Rolling): rolling-torque history
};

template <bool Friction, bool Rolling, bool Uniform>
[[gnu::always_inline]] inline double pair_loop(const PairKernelArgs& a, std::int64_t begin,
                                               std::int64_t end) {
  double mo = 0.0;
  const phys::ParticleView view = a.view;
  const std::int32_t* pi = a.pi;
  const std::int32_t* pj = a.pj;
  double* shear = a.shear;
  double* pf = a.pf;
  double* pt = a.pt;
  double* pr = a.pr;
  double* rhist = a.rhist;
  const double dt = a.dt;
#pragma omp simd reduction(max : mo)
  for (std::int64_t p = begin; p < end; ++p) {
    const std::int32_t i = pi[p], j = pj[p];
    const phys::PairConstants& c =
        Uniform ? a.pc[0] : a.pc[static_cast<std::size_t>(a.mat[i]) * a.nmat + a.mat[j]];
    Vec3 sh{0, 0, 0};
    if constexpr (Friction) sh = Vec3{shear[3 * p], shear[3 * p + 1], shear[3 * p + 2]};
    Vec3 rh{0, 0, 0};
    if constexpr (Rolling) rh = Vec3{rhist[3 * p], rhist[3 * p + 1], rhist[3 * p + 2]};
    phys::ContactResult r;
    double delta;
    phys::sphere_sphere_select<Friction, Rolling>(view, i, j, c, dt, sh, rh, r, delta);
    mo = mo > delta ? mo : delta;
    pf[3 * p] = r.force.x, pf[3 * p + 1] = r.force.y, pf[3 * p + 2] = r.force.z;
    if constexpr (Friction) {
      shear[3 * p] = sh.x, shear[3 * p + 1] = sh.y, shear[3 * p + 2] = sh.z;
      pt[3 * p] = r.torque.x, pt[3 * p + 1] = r.torque.y, pt[3 * p + 2] = r.torque.z;
      if constexpr (Rolling) {
        pr[3 * p] = r.roll.x, pr[3 * p + 1] = r.roll.y, pr[3 * p + 2] = r.roll.z;
        rhist[3 * p] = rh.x, rhist[3 * p + 1] = rh.y, rhist[3 * p + 2] = rh.z;
      }
    }
  }
  return mo;
}

#define DEMFEM_PAIR_KERNEL(F, R, U)                                                   \
  DEMFEM_CLONES double pair_kernel_##F##R##U(const PairKernelArgs& a, std::int64_t b, \
                                             std::int64_t e) {                        \
    return pair_loop<F != 0, R != 0, U != 0>(a, b, e);                                \
  }
DEMFEM_PAIR_KERNEL(0, 0, 0)
DEMFEM_PAIR_KERNEL(0, 0, 1)
DEMFEM_PAIR_KERNEL(1, 0, 0)
DEMFEM_PAIR_KERNEL(1, 0, 1)
DEMFEM_PAIR_KERNEL(1, 1, 0)
DEMFEM_PAIR_KERNEL(1, 1, 1)
#undef DEMFEM_PAIR_KERNEL

using PairKernel = double (*)(const PairKernelArgs&, std::int64_t, std::int64_t);
PairKernel pick_pair_kernel(bool friction, bool rolling, bool uniform) {
  if (!friction) return uniform ? pair_kernel_001 : pair_kernel_000;
  if (!rolling) return uniform ? pair_kernel_101 : pair_kernel_100;
  return uniform ? pair_kernel_111 : pair_kernel_110;
}

}  // namespace

struct DemSystem::Impl {
  DemSettings s;
  int threads = 1;
  std::size_t nmat = 0;
  std::vector<phys::PairConstants> pc;
  bool friction = false;     // some pair has friction or rolling resistance
  bool orientation = false;  // integrate the orientation (settings or a non-spherical particle)
  bool rolling = false;
  std::int64_t uniform_mat = -1;  // the material of every particle, -1 = mixed
  // Dilated polyhedra (polyhedra.cpp): the shape table, and whether some particle is one. A
  // system of spheres alone never runs their code (its bits and speed are those of before).
  detail::ShapeTable shapes;
  bool poly = false;
  std::size_t poly_count = 0;  // particles that are polyhedra (the threads' work estimate)
  std::vector<double> ptj;    // 3 per pair: torque on j (poly systems; pt is the torque on i)
  std::vector<double> paxis;  // 3 per pair: separating-axis cache of the narrow phase
  std::vector<std::int32_t> pfeat;  // 6 per pair: closest-feature cache (GJK warm start)
  std::vector<double> prot;         // 9 per particle: the polyhedra's rotations in a force pass

  ParticleState st;
  std::vector<double> tx, ty, tz;  // torque of the last step
  double t = 0.0;
  std::int64_t steps = 0;
  const std::atomic<bool>* cancel = nullptr;  // set_cancel_flag(): polled by advance()
  void check_cancel(std::int64_t done, std::int64_t of) const {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
      throw Cancelled("DEM advance cancelled after " + std::to_string(done) + " of " +
                      std::to_string(of) + " steps (a stop was requested)");
    }
  }
  double rmax = 0.0;
  double skin = 0.0;

  // Neighbour list: CSR rows of pairs (i, j > i), j ascending; transposed index per j.
  bool need_rebuild = true;
  std::vector<std::int64_t> row;    // n + 1
  std::vector<std::int32_t> nbr;    // j of each pair
  std::vector<std::int32_t> pown;   // i of each pair (flat pair loop)
  std::vector<std::int64_t> trow;   // n + 1
  std::vector<std::int64_t> tpair;  // pair index, grouped by j, i ascending
  std::vector<std::int32_t> tsrc;   // i of each transposed entry
  // One loop per particle in the gather instead of two (own row, transposed): the exit of a
  // short loop of varying length is mispredicted about once per particle.
  std::vector<std::int64_t> gather_row;   // n + 1
  std::vector<std::int64_t> gather_pair;  // pair of each entry
  std::vector<double> gather_sign;        // +1 own row (force on i), -1 transposed (force on j)
  std::vector<double> shear;              // 3 per pair
  std::vector<double> rhist;              // 3 per pair: rolling-torque history (only if rolling)
  std::vector<double> pf, pt, pr;         // 3 per pair: force on i, n x F_t, rolling torque on i
  std::vector<double> bx, by, bz;         // positions at the last refilter
  // Two-level list: a build from the cell grid keeps the candidate pairs within
  // r_i + r_j + skin (orow, onbr, same layout as row, nbr); the list proper holds those
  // within r_i + r_j + skin_in and is refiltered from them when some particle has moved
  // skin_in / 2. A settled bed's particles jitter, so a list with a thin skin would need a
  // grid build every few tens of steps; the refilter is a pass over the candidates.
  std::vector<std::int64_t> orow;
  std::vector<std::int32_t> onbr;
  double skin_in = 0.0;
  double out_disp = 0.0;  // bound of the largest displacement since the build, refilters summed
  double out_pair = 0.0;  // bound of d_i + d_j of any pair since the build, refilters summed
  std::int64_t refilters = 0;
  std::int64_t steps_at_update = -1;  // step of the last build or refilter

  // The list's skin adapts at each list update (build or refilter) to the steps since the
  // previous one, u:
  //  * u < 10 (a flow): skin_in grows by 1.5; beyond kInnerSkinMax x skin the list goes to one
  //    level (skin_in = skin). In a flow the build budget skin - skin_in (for d_i + d_j),
  //    checked against the summed refilter intervals, runs out about twice as fast as the
  //    whole skin (measured with the rule of twice the largest displacement: 96 builds and
  //    31 refilters against 53 builds in 1500 steps of 4096 falling spheres, 10 % slower). A
  //    refilter that may not grow the skin (the build budget) asks for a build;
  //  * u > 40 (a settled bed): skin_in shrinks by 1.5, to kInnerSkin x skin at least;
  //  * one level: a build more than 100 steps after the last goes back to two levels.
  // It depends on step counts only, and the list's non-touching pairs do not change the
  // result, so it keeps the bits. Returns false when a refilter must be a build instead.
  bool adapt_inner_skin(bool build, double pbuild = 0.0) {
    const std::int64_t since = steps - steps_at_update;
    const bool first = steps_at_update < 0;
    if (gpu != nullptr || s.list_skin > 0.0 || first) {  // fixed; one level on the device
      steps_at_update = steps;
      return true;
    }
    if (skin_in >= skin) {  // one level: updates are builds
      if (since > 100) skin_in = kInnerSkin * skin;
    } else if (since < 10) {
      const double grown = 1.5 * skin_in;
      if (build) {
        skin_in = grown > kInnerSkinMax * skin ? skin : grown;
      } else {
        if (grown > kInnerSkinMax * skin || pbuild > skin - grown) return false;
        skin_in = grown;
      }
    } else if (since > 40) {
      skin_in = std::max(kInnerSkin * skin, skin_in / 1.5);
    }
    steps_at_update = steps;
    return true;
  }
  double max_ov = 0.0;
  double adv_max_ov = 0.0;  // largest overlap over the steps of the last advance()
  std::int64_t rebuilds = 0;

  // Walls: all triangles (rigid walls first, then the flexible mesh) in one store.
  struct Wall {
    WallMesh mesh;
    std::int64_t vbase = 0, tbase = 0;  // offsets in the global vertex / triangle store
    std::array<double, 3> force{}, torque{};
    bool flexible = false;
    int body = -1;  // index in `bodies` when the wall is moved by its contact forces
  };
  std::vector<Wall> walls;  // rigid walls; the flexible one is `flex`
  detail::RigidMeshBodies bodies;  // walls moved by their contact forces (rigid_mesh_bodies.hpp)
  bool has_flex = false;
  Wall flex;
  std::vector<double> flex_x, flex_v, flex_a;  // kinematics at the start of advance()
  double flex_tau = 0.0;                       // time since that start
  std::vector<double> flex_force;              // per node, as ForceMode asked
  std::vector<double> node_buf;                // per node, forces of the current substep
  double flex_max_ov = 0.0;
  // global stores
  std::vector<double> vpos, vvel, vbuild;  // 3 per vertex
  std::vector<std::int32_t> tri_v, tri_e;  // 3 per triangle: vertices / edge ids
  std::vector<std::int32_t> tri_wall;      // wall index, -1 = flexible mesh
  std::vector<std::int32_t> tri_mat;
  std::vector<phys::RigidMotion> wall_motions;  // per rigid wall: its motion, for both backends
  std::size_t nedges = 0;
  bool walls_dirty = true;  // topology must be rebuilt
  bool walls_moving = false;
  // particle -> candidate triangles (built with the neighbour list)
  std::vector<std::int64_t> prow;
  std::vector<std::int32_t> ptri;
  // per-particle wall contact slots
  std::vector<std::int64_t> wkey;  // kMaxWallContacts per particle, -1 = empty
  std::vector<double> wshear;      // 3 per slot
  std::vector<double> wroll;       // 3 per slot: rolling-torque history (only if rolling)
  std::vector<double> wf, wp, wb;  // force on particle, contact point, barycentric weights
  std::vector<std::int32_t> wtri;
  std::vector<std::uint8_t> wcount;

  CudaBackend* gpu = nullptr;
  DemSystem::Timings timing;

  // Particle ranges of the threads in forces_and_kick(), moved towards equal busy times. The
  // bottom of a bed has more contacts per particle and the wall contacts, so equal counts
  // leave one thread waiting (measured on the 20,000-sphere bed: 0.3 of its time). The
  // result does not depend on the ranges (every sum has a fixed order; see
  // forces_and_kick()), so timing them is safe for bitwise reproducibility.
  struct ThreadBalance {
    std::vector<std::int64_t> split;                 // T + 1 range bounds
    std::vector<double> busy;                        // per thread: time before the barrier, s
    std::vector<std::vector<std::int64_t>> waiting;  // per thread: particles gathered after it
    void ensure(int threads, std::int64_t count) {
      const auto T = static_cast<std::size_t>(threads);
      if (split.size() == T + 1 && split.back() == count) return;
      split.resize(T + 1);
      for (std::size_t k = 0; k <= T; ++k)
        split[k] = count * static_cast<std::int64_t>(k) / static_cast<std::int64_t>(T);
      busy.assign(T, 0.0);
      waiting.resize(T);
    }
    // New bounds from each thread's particles per second, halfway towards the balanced ones
    // (timings on a shared machine are noisy).
    void adapt() {
      const std::size_t T = busy.size();
      if (T < 2) return;
      std::vector<double> rate(T);
      double sum = 0.0;
      for (std::size_t k = 0; k < T; ++k) {
        const double cnt = static_cast<double>(split[k + 1] - split[k]);
        rate[k] = busy[k] > 0.0 && cnt > 0.0 ? cnt / busy[k] : 0.0;
        if (!(rate[k] > 0.0)) return;  // no usable timing
        sum += rate[k];
      }
      const std::int64_t count = split.back();
      double acc = 0.0;
      for (std::size_t k = 1; k < T; ++k) {
        acc += rate[k - 1];
        const double target = static_cast<double>(count) * acc / sum;
        const auto next = static_cast<std::int64_t>(0.5 * (static_cast<double>(split[k]) + target));
        // at least one particle per thread, bounds ascending
        split[k] = std::clamp<std::int64_t>(next, split[k - 1] + 1,
                                            count - static_cast<std::int64_t>(T - k));
      }
    }
  } balance;

  ~Impl() { cuda_backend_destroy(gpu); }

  // ---------------------------------------------------------------------------------------
  void setup_pairs() {
    nmat = s.materials.size();
    pc.resize(nmat * nmat);
    friction = rolling = false;
    for (std::size_t a = 0; a < nmat; ++a)
      for (std::size_t b = 0; b < nmat; ++b) {
        const auto& ma = s.materials[a];
        const auto& mb = s.materials[b];
        const auto& p = s.pairs[a * nmat + b];
        pc[a * nmat + b] =
            phys::pair_constants(ma.youngs_modulus, ma.poisson_ratio, mb.youngs_modulus,
                                 mb.poisson_ratio, p.restitution, p.friction, p.rolling_friction,
                                 p.rocking_damping);
        friction = friction || p.friction > 0.0 || p.rolling_friction > 0.0;
        rolling = rolling || p.rolling_friction > 0.0;
      }
  }

  std::size_t n() const { return st.px.size(); }
  // Threads for the particle loops: small systems run on one thread, where the fork/join
  // of a parallel region costs more than the work (results do not depend on it). The work
  // is counted in sphere-steps: a polyhedron step costs about kPolyWork of them (measured by
  // bench/poly_throughput: 20-26 for rocks of 30 triangles), so beds from about 80 rocks on
  // run threaded.
  static constexpr std::size_t kPolyWork = 24;
  int nt() const { return n() + (kPolyWork - 1) * poly_count >= 2048 ? threads : 1; }

  // ---------------------------------------------------------------------------------------
  // Wall topology: unique edge ids over the whole store so that a contact at an edge or a
  // vertex shared by neighbouring triangles is counted once.
  void build_wall_store() {
    vpos.clear();
    vvel.clear();
    tri_v.clear();
    tri_wall.clear();
    tri_mat.clear();
    auto append = [&](Wall& w, std::int32_t widx) {
      w.vbase = static_cast<std::int64_t>(vpos.size() / 3);
      w.tbase = static_cast<std::int64_t>(tri_v.size() / 3);
      vpos.insert(vpos.end(), w.mesh.vertices.begin(), w.mesh.vertices.end());
      for (std::size_t k = 0; k < w.mesh.triangles.size(); ++k)
        tri_v.push_back(static_cast<std::int32_t>(w.vbase + w.mesh.triangles[k]));
      for (std::size_t k = 0; k < w.mesh.triangles.size() / 3; ++k) {
        tri_wall.push_back(widx);
        tri_mat.push_back(w.mesh.material);
      }
    };
    for (std::size_t w = 0; w < walls.size(); ++w) append(walls[w], static_cast<std::int32_t>(w));
    if (has_flex) {
      append(flex, -1);
      if (flex_x.size() == flex.mesh.vertices.size())
        std::copy(flex_x.begin(), flex_x.end(), vpos.begin() + 3 * flex.vbase);
    }
    vvel.assign(vpos.size(), 0.0);
    vbuild = vpos;
    // unique undirected edges
    const std::size_t ntri = tri_v.size() / 3;
    std::vector<std::pair<std::pair<std::int32_t, std::int32_t>, std::int64_t>> edges;
    edges.reserve(3 * ntri);
    for (std::size_t k = 0; k < ntri; ++k)
      for (int e = 0; e < 3; ++e) {
        std::int32_t a = tri_v[3 * k + e], b = tri_v[3 * k + (e + 1) % 3];
        if (a > b) std::swap(a, b);
        edges.push_back({{a, b}, static_cast<std::int64_t>(3 * k + e)});
      }
    std::sort(edges.begin(), edges.end());
    tri_e.assign(3 * ntri, 0);
    std::int32_t id = -1;
    for (std::size_t k = 0; k < edges.size(); ++k) {
      if (k == 0 || edges[k].first != edges[k - 1].first) ++id;
      tri_e[edges[k].second] = id;
    }
    nedges = static_cast<std::size_t>(id + 1);
    walls_moving = has_flex || !bodies.empty();
    wall_motions.clear();
    for (auto& w : walls) {
      walls_moving = walls_moving || w.mesh.motion.kind != WallMotion::Kind::fixed;
      wall_motions.push_back(rigid_motion(w.mesh.motion));
    }
    walls_dirty = false;
    need_rebuild = true;
  }

  // Vertex positions and velocities of the walls at time tt (tau: time into the advance()),
  // by the kinematics shared with the CUDA backend (physics/wall_motion.hpp).
  void update_walls(double tt, double tau) {
    for (std::size_t wi = 0; wi < walls.size(); ++wi) {
      const Wall& w = walls[wi];
      if (w.body >= 0) {
        bodies.place(w.body, vpos.data() + 3 * w.vbase, vvel.data() + 3 * w.vbase);
        continue;
      }
      if (w.mesh.motion.kind == WallMotion::Kind::fixed) continue;
      const phys::RigidPose pose = phys::rigid_pose(wall_motions[wi], tt);
      const std::size_t nv = w.mesh.vertices.size() / 3;
      double* x = vpos.data() + 3 * w.vbase;
      double* v = vvel.data() + 3 * w.vbase;
      const double* x0 = w.mesh.vertices.data();
      for (std::size_t k = 0; k < nv; ++k)
        phys::rigid_vertex(pose, x0 + 3 * k, x + 3 * k, v + 3 * k);
    }
    if (has_flex && flex_x.size() == flex.mesh.vertices.size()) {
      const std::size_t nv = flex.mesh.vertices.size() / 3;
      double* x = vpos.data() + 3 * flex.vbase;
      double* v = vvel.data() + 3 * flex.vbase;
      for (std::size_t k = 0; k < 3 * nv; ++k)
        phys::flexible_node(flex_x[k], flex_v[k], flex_a[k], tau, x[k], v[k]);
    }
  }

  double wall_displacement() const {
    if (!walls_moving) return 0.0;
    double m2 = 0.0;
    for (std::size_t k = 0; k < vpos.size(); k += 3) {
      const double dx = vpos[k] - vbuild[k], dy = vpos[k + 1] - vbuild[k + 1],
                   dz = vpos[k + 2] - vbuild[k + 2];
      m2 = std::max(m2, dx * dx + dy * dy + dz * dz);
    }
    return std::sqrt(m2);
  }

  // ---------------------------------------------------------------------------------------
  // Neighbour list: uniform grid by counting sort, pairs within r_i + r_j + skin.
  void rebuild() {
    const std::size_t np = n();
    ++rebuilds;
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
    for (std::size_t i = 0; i < np; ++i)
      for (int d = 0; d < 3; ++d) {
        lo[d] = std::min(lo[d], P[d][i]);
        hi[d] = std::max(hi[d], P[d][i]);
      }
    if (np == 0)
      for (int d = 0; d < 3; ++d) lo[d] = hi[d] = 0.0;
    double h = std::max(2.0 * rmax + skin, 1e-12);
    std::int64_t dim[3];
    for (;;) {
      std::int64_t tot = 1;
      for (int d = 0; d < 3; ++d) {
        dim[d] = std::max<std::int64_t>(1, static_cast<std::int64_t>((hi[d] - lo[d]) / h) + 1);
        tot *= dim[d];
      }
      if (tot <= static_cast<std::int64_t>(4 * np + 4096)) break;
      h *= 1.26;  // a sparse cloud: coarser cells keep the grid small
    }
    const std::int64_t ncell = dim[0] * dim[1] * dim[2];
    const double inv_h = 1.0 / h;
    std::vector<std::int32_t> cell(np);
    auto cell_coord = [&](double x, int d) {
      return std::clamp<std::int64_t>(static_cast<std::int64_t>((x - lo[d]) * inv_h), 0,
                                      dim[d] - 1);
    };
    for (std::size_t i = 0; i < np; ++i)
      cell[i] = static_cast<std::int32_t>(
          (cell_coord(P[2][i], 2) * dim[1] + cell_coord(P[1][i], 1)) * dim[0] +
          cell_coord(P[0][i], 0));
    std::vector<std::int64_t> cstart(ncell + 1, 0);
    for (std::size_t i = 0; i < np; ++i) ++cstart[cell[i] + 1];
    for (std::int64_t c = 0; c < ncell; ++c) cstart[c + 1] += cstart[c];
    std::vector<std::int32_t> sorted(np);
    {
      std::vector<std::int64_t> fill(cstart.begin(), cstart.end() - 1);
      for (std::size_t i = 0; i < np; ++i) sorted[fill[cell[i]]++] = static_cast<std::int32_t>(i);
    }
    // Positions and radii in cell order: the scan reads each neighbour cell's spheres from
    // contiguous memory (in particle order they are scattered once a bed has flowed).
    const std::int64_t sn = static_cast<std::int64_t>(np);
    std::vector<double> sx(np), sy(np), sz(np), sr(np);
    const double* R = st.radius.data();
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t k = 0; k < sn; ++k) {
      const std::int32_t i = sorted[k];
      sx[k] = P[0][i], sy[k] = P[1][i], sz[k] = P[2][i], sr[k] = R[i];
    }
    auto scan = [&](std::size_t i, auto&& emit) {
      const double xi = P[0][i], yi = P[1][i], zi = P[2][i], ri = R[i];
      const std::int64_t cx = cell_coord(xi, 0), cy = cell_coord(yi, 1), cz = cell_coord(zi, 2);
      for (std::int64_t z = std::max<std::int64_t>(0, cz - 1); z <= std::min(dim[2] - 1, cz + 1);
           ++z)
        for (std::int64_t y = std::max<std::int64_t>(0, cy - 1); y <= std::min(dim[1] - 1, cy + 1);
             ++y) {
          // the three cells x - 1 .. x + 1 of a row are consecutive in cell order
          const std::int64_t c0 = (z * dim[1] + y) * dim[0];
          const std::int64_t k1 = cstart[c0 + std::min(dim[0] - 1, cx + 1) + 1];
          for (std::int64_t k = cstart[c0 + std::max<std::int64_t>(0, cx - 1)]; k < k1; ++k) {
            const std::size_t j = static_cast<std::size_t>(sorted[k]);
            if (j <= i) continue;
            const double dx = sx[k] - xi, dy = sy[k] - yi, dz = sz[k] - zi;
            const double cut = ri + sr[k] + skin;
            if (dx * dx + dy * dy + dz * dz < cut * cut) emit(static_cast<std::int32_t>(j));
          }
        }
    };
    // One scan: the particles in nt() contiguous chunks, each chunk's sorted rows appended to
    // its own buffer, then the buffers copied into place (the rows of a scan per particle,
    // for any thread count).
    std::vector<std::int64_t> nrow(np + 1, 0);
    const std::int64_t chunks = nt();
    std::vector<std::vector<std::int32_t>> found(static_cast<std::size_t>(chunks));
#pragma omp parallel for num_threads(nt()) schedule(static, 1)
    for (std::int64_t ch = 0; ch < chunks; ++ch) {
      const std::int64_t b0 = sn * ch / chunks, b1 = sn * (ch + 1) / chunks;
      auto& buf = found[static_cast<std::size_t>(ch)];
      buf.reserve(static_cast<std::size_t>(8 * (b1 - b0)));
      for (std::int64_t i = b0; i < b1; ++i) {
        const std::size_t start = buf.size();
        scan(static_cast<std::size_t>(i), [&](std::int32_t j) { buf.push_back(j); });
        std::sort(buf.begin() + static_cast<std::ptrdiff_t>(start), buf.end());
        nrow[i + 1] = static_cast<std::int64_t>(buf.size() - start);
      }
    }
    for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
    std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static, 1)
    for (std::int64_t ch = 0; ch < chunks; ++ch) {
      const auto& buf = found[static_cast<std::size_t>(ch)];
      std::copy(buf.begin(), buf.end(), nnbr.begin() + nrow[sn * ch / chunks]);
    }
    orow.swap(nrow);
    onbr.swap(nnbr);
    out_disp = 0.0;
    out_pair = 0.0;
    adapt_inner_skin(true);
    // triangles: binned into the particle cells their AABB (grown by rmax + skin) touches
    prow.assign(np + 1, 0);
    ptri.clear();
    const std::size_t ntri = tri_v.size() / 3;
    if (ntri > 0 && np > 0) {
      const double grow = rmax + skin;
      std::vector<std::int64_t> tcount(ncell + 1, 0);
      std::vector<std::array<std::int64_t, 6>> box(ntri);
      for (std::size_t k = 0; k < ntri; ++k) {
        double tl[3] = {1e300, 1e300, 1e300}, th[3] = {-1e300, -1e300, -1e300};
        for (int e = 0; e < 3; ++e)
          for (int d = 0; d < 3; ++d) {
            const double x = vpos[3 * tri_v[3 * k + e] + d];
            tl[d] = std::min(tl[d], x - grow);
            th[d] = std::max(th[d], x + grow);
          }
        bool out = false;
        for (int d = 0; d < 3; ++d) {
          if (th[d] < lo[d] || tl[d] > lo[d] + dim[d] * h) out = true;
          box[k][d] = cell_coord(tl[d], d);
          box[k][3 + d] = cell_coord(th[d], d);
        }
        if (out)
          box[k][0] = -1;
        else
          for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
            for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
              for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
                ++tcount[(z * dim[1] + y) * dim[0] + x + 1];
      }
      for (std::int64_t c = 0; c < ncell; ++c) tcount[c + 1] += tcount[c];
      std::vector<std::int32_t> tbin(static_cast<std::size_t>(tcount[ncell]));
      {
        std::vector<std::int64_t> fill(tcount.begin(), tcount.end() - 1);
        for (std::size_t k = 0; k < ntri; ++k) {
          if (box[k][0] < 0) continue;
          for (std::int64_t z = box[k][2]; z <= box[k][5]; ++z)
            for (std::int64_t y = box[k][1]; y <= box[k][4]; ++y)
              for (std::int64_t x = box[k][0]; x <= box[k][3]; ++x)
                tbin[fill[(z * dim[1] + y) * dim[0] + x]++] = static_cast<std::int32_t>(k);
        }
      }
      auto near = [&](std::size_t i, std::int32_t k) {
        const Vec3 p{P[0][i], P[1][i], P[2][i]};
        const double* v = vpos.data();
        const std::int32_t* tv = tri_v.data() + 3 * k;
        const auto cp =
            phys::closest_point_triangle(p, Vec3{v[3 * tv[0]], v[3 * tv[0] + 1], v[3 * tv[0] + 2]},
                                         Vec3{v[3 * tv[1]], v[3 * tv[1] + 1], v[3 * tv[1] + 2]},
                                         Vec3{v[3 * tv[2]], v[3 * tv[2] + 1], v[3 * tv[2] + 2]});
        const double cut = R[i] + skin;
        return phys::norm2(p - cp.point) < cut * cut;
      };
#pragma omp parallel for num_threads(nt()) schedule(static)
      for (std::int64_t i = 0; i < sn; ++i) {
        const std::int32_t c = cell[i];
        std::int64_t cnt = 0;
        for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
          if (near(static_cast<std::size_t>(i), tbin[k])) ++cnt;
        prow[i + 1] = cnt;
      }
      for (std::size_t i = 0; i < np; ++i) prow[i + 1] += prow[i];
      ptri.resize(static_cast<std::size_t>(prow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static)
      for (std::int64_t i = 0; i < sn; ++i) {
        const std::int32_t c = cell[i];
        std::int64_t o = prow[i];
        for (std::int64_t k = tcount[c]; k < tcount[c + 1]; ++k)
          if (near(static_cast<std::size_t>(i), tbin[k])) ptri[o++] = tbin[k];
      }
    }
    vbuild = vpos;
    need_rebuild = false;
    refilter();
  }

  // The pair list proper: the candidates of the last build closer than r_i + r_j + skin_in
  // now. Springs are carried over from the previous list (merge of sorted rows).
  void refilter() {
    const std::size_t np = n();
    const std::int64_t sn = static_cast<std::int64_t>(np);
    ++refilters;
    const double* P[3] = {st.px.data(), st.py.data(), st.pz.data()};
    const double* R = st.radius.data();
    std::vector<std::int64_t> nrow(np + 1, 0);
    auto keep = [&](std::int64_t i, std::int32_t j) {
      const double dx = P[0][j] - P[0][i], dy = P[1][j] - P[1][i], dz = P[2][j] - P[2][i];
      const double cut = R[i] + R[j] + skin_in;
      return dx * dx + dy * dy + dz * dz < cut * cut;
    };
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      std::int64_t c = 0;
      for (std::int64_t k = orow[i]; k < orow[i + 1]; ++k) c += keep(i, onbr[k]) ? 1 : 0;
      nrow[i + 1] = c;
    }
    for (std::size_t i = 0; i < np; ++i) nrow[i + 1] += nrow[i];
    std::vector<std::int32_t> nnbr(static_cast<std::size_t>(nrow[np]));
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      std::int64_t c = nrow[i];
      for (std::int64_t k = orow[i]; k < orow[i + 1]; ++k)
        if (keep(i, onbr[k])) nnbr[c++] = onbr[k];
    }
    // carry the tangential springs over (merge of the sorted old and new rows)
    const std::size_t npair = nnbr.size();
    std::vector<double> nshear, nrhist, naxis;
    std::vector<std::int32_t> nfeat;
    if (rolling) nrhist.assign(3 * npair, 0.0);  // carried with the springs
    if (poly) naxis.assign(3 * npair, 0.0);      // and the narrow phase's caches
    if (poly) nfeat.assign(6 * npair, -1);
    if (friction) nshear.assign(3 * npair, 0.0);
    if ((friction || poly) && row.size() == np + 1) {
      const bool carry_axis =
          poly && paxis.size() == 3 * nbr.size() && pfeat.size() == 6 * nbr.size();
#pragma omp parallel for num_threads(nt()) schedule(static)
      for (std::int64_t i = 0; i < sn; ++i) {
        std::int64_t a = row[i], b = nrow[i];
        while (a < row[i + 1] && b < nrow[i + 1]) {
          if (nbr[a] < nnbr[b]) {
            ++a;
          } else if (nbr[a] > nnbr[b]) {
            ++b;
          } else {
            if (friction)
              for (int d = 0; d < 3; ++d) nshear[3 * b + d] = shear[3 * a + d];
            if (friction && rolling && rhist.size() == shear.size())
              for (int d = 0; d < 3; ++d) nrhist[3 * b + d] = rhist[3 * a + d];
            if (carry_axis) {
              for (int d = 0; d < 3; ++d) naxis[3 * b + d] = paxis[3 * a + d];
              for (int d = 0; d < 6; ++d) nfeat[6 * b + d] = pfeat[6 * a + d];
            }
            ++a, ++b;
          }
        }
      }
    }
    row.swap(nrow);
    nbr.swap(nnbr);
    shear.swap(nshear);
    rhist.swap(nrhist);
    paxis.swap(naxis);
    pfeat.swap(nfeat);
    pown.resize(npair);
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i)
      std::fill(pown.begin() + row[i], pown.begin() + row[i + 1], static_cast<std::int32_t>(i));
    uniform_mat = np > 0 ? st.material[0] : -1;
    for (std::size_t i = 0; i < np && uniform_mat >= 0; ++i)
      if (st.material[i] != uniform_mat) uniform_mat = -1;
    pf.assign(3 * npair, 0.0);
    if (friction || poly)
      pt.assign(3 * npair, 0.0);
    else
      pt.clear();
    if (poly)
      ptj.assign(3 * npair, 0.0);
    else
      ptj.clear();
    if (rolling)
      pr.assign(3 * npair, 0.0);
    else
      pr.clear();
    // transposed index: for each j the pairs (i, j), i ascending (counting sort is stable)
    trow.assign(np + 1, 0);
    for (std::size_t p = 0; p < npair; ++p) ++trow[nbr[p] + 1];
    for (std::size_t i = 0; i < np; ++i) trow[i + 1] += trow[i];
    tpair.resize(npair);
    tsrc.resize(npair);
    {
      std::vector<std::int64_t> fill(trow.begin(), trow.end() - 1);
      for (std::size_t i = 0; i < np; ++i)
        for (std::int64_t p = row[i]; p < row[i + 1]; ++p) {
          const std::int64_t k = fill[nbr[p]]++;
          tpair[k] = p;
          tsrc[k] = static_cast<std::int32_t>(i);
        }
    }
    // the gather's list: per particle its own row's pairs (sign +1), then its transposed
    // pairs (sign -1), in the order of the two loops it replaces
    // (row and trow are prefix sums, so particle i's entries start at row[i] + trow[i])
    gather_row.resize(np + 1);
    gather_pair.resize(2 * npair);
    gather_sign.resize(2 * npair);
    bx.resize(np), by.resize(np), bz.resize(np);
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i <= sn; ++i) gather_row[i] = row[i] + trow[i];
#pragma omp parallel for num_threads(nt()) schedule(static)
    for (std::int64_t i = 0; i < sn; ++i) {
      std::int64_t g = gather_row[i];
      for (std::int64_t p = row[i]; p < row[i + 1]; ++p) gather_pair[g] = p, gather_sign[g++] = 1.0;
      for (std::int64_t k = trow[i]; k < trow[i + 1]; ++k)
        gather_pair[g] = tpair[k], gather_sign[g++] = -1.0;
      bx[i] = st.px[i], by[i] = st.py[i], bz[i] = st.pz[i];
    }
  }

  // ---------------------------------------------------------------------------------------
  // Forces and the second half kick, in one parallel region. Each thread owns a contiguous
  // range of particles (rows of the pair list) and walks it in blocks: the pair forces of the
  // block's rows into the per-pair slots (vectorised kernel), then, while those slots are
  // still in cache, the gather of the block's particles: own-row slots in row order, minus
  // the transposed slots (pairs j < i, i ascending), walls, gravity, kick. A particle whose
  // pairs reach back into an earlier thread's range (the first layer of each range) waits
  // for a barrier, so that no thread reads a slot or a velocity that another thread has not
  // written yet or has already kicked; after the barrier the threads share the waiting
  // particles out evenly. Every sum has a fixed order and every pair is independent, so the
  // result is bitwise identical for any thread count, range bounds and block size.
  // Poly: some particle is a polyhedron (polyhedra.cpp): the pairs go through the narrow
  // phase, each pair slot holds the torques on both bodies (pt on i, ptj on j), polyhedra have
  // their own wall contacts and angular kick, and torques are always summed (a normal force
  // off the centre of mass turns a polyhedron).
  template <bool Friction, bool Poly = false>
  void forces_and_kick() {
    const std::int64_t sn = static_cast<std::int64_t>(n());
    PairKernelArgs a{};
    a.view = phys::ParticleView{st.px.data(), st.py.data(),     st.pz.data(),  st.vx.data(),
                                st.vy.data(), st.vz.data(),     st.wx.data(),  st.wy.data(),
                                st.wz.data(), st.radius.data(), st.mass.data()};
    a.pi = pown.data();
    a.pj = nbr.data();
    a.mat = st.material.data();
    a.pc = uniform_mat >= 0 ? pc.data() + uniform_mat * (nmat + 1) : pc.data();
    a.nmat = nmat;
    a.dt = s.dt;
    a.shear = shear.data();
    a.pf = pf.data();
    a.pt = pt.data();
    a.pr = pr.data();
    a.rhist = rhist.data();
    const PairKernel kern = pick_pair_kernel(Friction, Friction && rolling, uniform_mat >= 0);
    detail::PolyParticles pp{};
    detail::PolyPairs pa{};
    if constexpr (Poly) {
      pp = poly_particles(a.view);
      prot.resize(9 * n());
      detail::poly_rotations(pp, prot.data(), sn, nt());
      pp.rot = prot.data();
      pa = detail::PolyPairs{pown.data(), nbr.data(), st.material.data(), pc.data(), nmat,
                             s.dt,        Friction,   rolling,            shear.data(), rhist.data(),
                             pf.data(),   pt.data(),  ptj.data(),         paxis.data(),
                             pfeat.data()};
    }

    const double h = 0.5 * s.dt;
    const double g[3] = {s.gravity[0], s.gravity[1], s.gravity[2]};
    const bool walls_on = !tri_v.empty();
    const phys::WallView wv = wall_view();
    const phys::ParticleView& view = a.view;
    const double* PF = pf.data();
    const double* PT = pt.data();
    const double* PR = pr.data();
    const double* PTJ = ptj.data();
    const bool roll = rolling;
    auto gather = [&](std::int64_t i, double& mo, double& fmo) {
      double fx = 0, fy = 0, fz = 0;
      double qx = 0, qy = 0, qz = 0;
      const double ri = st.radius[i];
      // own row (pairs i < j) in row order, then the transposed pairs (j < i) in order
      // x + (-1 y) is x - y exactly: the sums are those of a loop over each part
      for (std::int64_t k = gather_row[i]; k < gather_row[i + 1]; ++k) {
        const std::int64_t p = gather_pair[k];
        const double sg = gather_sign[k];
        fx += sg * PF[3 * p], fy += sg * PF[3 * p + 1], fz += sg * PF[3 * p + 2];
        if constexpr (Poly) {
          const double* T = sg > 0.0 ? PT : PTJ;
          qx += T[3 * p], qy += T[3 * p + 1], qz += T[3 * p + 2];
        } else if constexpr (Friction) {
          qx += ri * PT[3 * p], qy += ri * PT[3 * p + 1], qz += ri * PT[3 * p + 2];
          if (roll) qx += sg * PR[3 * p], qy += sg * PR[3 * p + 1], qz += sg * PR[3 * p + 2];
        }
      }
      if (walls_on && (wv.prow[i] != wv.prow[i + 1] || wv.wcount[i] != 0)) {
        Vec3 f{fx, fy, fz}, q{qx, qy, qz};
        if (Poly && st.shape_id[i] >= 0)
          detail::poly_wall_contacts(pp, wv, i, pc.data() + st.material[i] * nmat, s.dt, Friction,
                                     f, q, mo, fmo);
        else
          wall_contacts_apart<Friction>(view, wv, i, pc.data() + st.material[i] * nmat, s.dt, f,
                                        q, mo, fmo);
        fx = f.x, fy = f.y, fz = f.z;
        qx = q.x, qy = q.y, qz = q.z;
      }
      const double m = st.mass[i];
      fx += m * g[0], fy += m * g[1], fz += m * g[2];
      st.fx[i] = fx, st.fy[i] = fy, st.fz[i] = fz;
      phys::kick(st.vx[i], st.vy[i], st.vz[i], fx, fy, fz, h / m);
      if constexpr (Poly) {
        tx[i] = qx, ty[i] = qy, tz[i] = qz;
        detail::poly_angular_kick(pp, i, st.wx.data(), st.wy.data(), st.wz.data(),
                                  Vec3{qx, qy, qz}, h);
      } else if constexpr (Friction) {
        tx[i] = qx, ty[i] = qy, tz[i] = qz;
        phys::kick(st.wx[i], st.wy[i], st.wz[i], qx, qy, qz, h / st.inertia[i]);
      }
    };
    constexpr std::int64_t kBlock = 256;  // particles per block: ~1500 pairs, ~150 kB of slots
    const int T = nt();
    balance.ensure(T, sn);
    for (auto& list : balance.waiting) list.clear();
    double mo = 0.0, fmo = 0.0;
    int active = T;
#pragma omp parallel num_threads(T) reduction(max : mo, fmo)
    {
      const int k = omp_get_thread_num(), nth = omp_get_num_threads();
      // fewer threads than asked (a nested region, a thread limit): equal ranges
      if (k == 0) active = nth;
      const double start = omp_get_wtime();
      const std::int64_t lo = nth == T ? balance.split[k] : sn * k / nth;
      const std::int64_t hi = nth == T ? balance.split[k + 1] : sn * (k + 1) / nth;
      auto waits = [&](std::int64_t i) { return trow[i] < trow[i + 1] && tsrc[trow[i]] < lo; };
      std::vector<std::int64_t>& waiting = balance.waiting[k];
      for (std::int64_t b0 = lo; b0 < hi; b0 += kBlock) {
        const std::int64_t b1 = std::min(hi, b0 + kBlock);
        if constexpr (Poly)
          mo = std::max(mo, detail::poly_pair_forces(pp, pa, row[b0], row[b1]));
        else
          mo = std::max(mo, kern(a, row[b0], row[b1]));
        for (std::int64_t i = b0; i < b1; ++i)
          if (waits(i))
            waiting.push_back(i);
          else
            gather(i, mo, fmo);
      }
      balance.busy[k] = omp_get_wtime() - start;
#pragma omp barrier
      // the waiting particles of all threads, shared out evenly (each gather is independent)
      std::int64_t total = 0;
      for (const auto& list : balance.waiting) total += static_cast<std::int64_t>(list.size());
      const std::int64_t w0 = total * k / nth, w1 = total * (k + 1) / nth;
      std::int64_t base = 0;
      for (std::size_t th = 0; th < balance.waiting.size() && base < w1; ++th) {
        const auto& list = balance.waiting[th];
        const std::int64_t len = static_cast<std::int64_t>(list.size());
        for (std::int64_t m = std::max(w0, base); m < std::min(w1, base + len); ++m)
          gather(list[m - base], mo, fmo);
        base += len;
      }
    }
    if (active == T) balance.adapt();
    max_ov = mo;
    adv_max_ov = std::max(adv_max_ov, mo);
    flex_max_ov = std::max(flex_max_ov, fmo);
  }

  detail::PolyParticles poly_particles(const phys::ParticleView& view) const {
    return detail::PolyParticles{view,          st.qw.data(),      st.qx.data(),    st.qy.data(),
                                 st.qz.data(),  st.ix.data(),      st.iy.data(),    st.iz.data(),
                                 st.inertia.data(), st.scale.data(), st.shape_id.data(),
                                 shapes.view()};
  }

  // Kick + drift of a system with polyhedra (polyhedra.cpp): per particle, spheres and rigid
  // bodies alike.
  double poly_kick_drift() {
    const bool have_build = bx.size() == n();
    detail::PolyDrift d{static_cast<std::int64_t>(n()),
                        s.dt,
                        nt(),
                        st.px.data(),
                        st.py.data(),
                        st.pz.data(),
                        st.vx.data(),
                        st.vy.data(),
                        st.vz.data(),
                        st.wx.data(),
                        st.wy.data(),
                        st.wz.data(),
                        st.qw.data(),
                        st.qx.data(),
                        st.qy.data(),
                        st.qz.data(),
                        st.fx.data(),
                        st.fy.data(),
                        st.fz.data(),
                        tx.data(),
                        ty.data(),
                        tz.data(),
                        st.mass.data(),
                        st.inertia.data(),
                        st.ix.data(),
                        st.iy.data(),
                        st.iz.data(),
                        st.shape_id.data(),
                        have_build ? bx.data() : nullptr,
                        have_build ? by.data() : nullptr,
                        have_build ? bz.data() : nullptr};
    return detail::poly_kick_drift(d);
  }

  phys::WallView wall_view() {
    phys::WallView v{vpos.data(),     vvel.data(), tri_v.data(), tri_e.data(), tri_mat.data(),
                     tri_wall.data(), prow.data(), ptri.data(),  wkey.data(),  wshear.data(),
                     wf.data(),       wp.data(),   wb.data(),    wtri.data(),  wcount.data()};
    v.wroll = rolling ? wroll.data() : nullptr;
    if (walls_moving && !wall_motions.empty()) v.motion = wall_motions.data(), v.time = t;
    return v;
  }

  // Sum of the two largest displacements since the last list update (bx): bounds d_i + d_j
  // of every pair. Per-thread top two, combined in thread order (max is exact: any order
  // gives the same value).
  std::vector<std::array<double, 2>> top_two;  // per thread (member: no allocation per call)
  double two_largest_displacements() {
    const std::int64_t sn = static_cast<std::int64_t>(n());
    const int T = nt();
    top_two.assign(static_cast<std::size_t>(T), {0.0, 0.0});
#pragma omp parallel num_threads(T)
    {
      double a = 0.0, b = 0.0;  // a >= b, squared
#pragma omp for schedule(static)
      for (std::int64_t i = 0; i < sn; ++i) {
        const double dx = st.px[i] - bx[i], dy = st.py[i] - by[i], dz = st.pz[i] - bz[i];
        const double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 > a) {
          b = a;
          a = d2;
        } else if (d2 > b) {
          b = d2;
        }
      }
      top_two[static_cast<std::size_t>(omp_get_thread_num())] = {a, b};
    }
    double a = 0.0, b = 0.0;
    for (const auto& [ta, tb] : top_two) {
      b = std::max(b, std::min(a, ta));
      a = std::max(a, ta);
      b = std::max(b, tb);
    }
    return std::sqrt(a) + std::sqrt(b);
  }

  // Half kick + drift; returns the largest displacement since the last list update. The
  // orientation is advanced in a second loop: with only small rotations in this step (the
  // usual case) it runs in SIMD lanes without sin/cos; the per-particle arithmetic is the
  // same either way.
  template <bool Friction>
  double kick_drift() {
    if (poly) return poly_kick_drift();
    const std::int64_t sn = static_cast<std::int64_t>(n());
    const double dt = s.dt, h = 0.5 * s.dt;
    double m2 = 0.0, w2max = 0.0;
    const bool have_build = bx.size() == n();
    double *vx = st.vx.data(), *vy = st.vy.data(), *vz = st.vz.data();
    double *px = st.px.data(), *py = st.py.data(), *pz = st.pz.data();
    double *wx = st.wx.data(), *wy = st.wy.data(), *wz = st.wz.data();
    const double *fx = st.fx.data(), *fy = st.fy.data(), *fz = st.fz.data();
    const double *mass = st.mass.data(), *inertia = st.inertia.data();
    const double *Tx = tx.data(), *Ty = ty.data(), *Tz = tz.data();
    const double *Bx = bx.data(), *By = by.data(), *Bz = bz.data();
#pragma omp parallel for simd num_threads(nt()) schedule(static) reduction(max : m2, w2max)
    for (std::int64_t i = 0; i < sn; ++i) {
      const double hm = h / mass[i];
      phys::kick(vx[i], vy[i], vz[i], fx[i], fy[i], fz[i], hm);
      px[i] += dt * vx[i];
      py[i] += dt * vy[i];
      pz[i] += dt * vz[i];
      if constexpr (Friction) {
        phys::kick(wx[i], wy[i], wz[i], Tx[i], Ty[i], Tz[i], h / inertia[i]);
      }
      const double w2 = wx[i] * wx[i] + wy[i] * wy[i] + wz[i] * wz[i];
      w2max = w2max > w2 ? w2max : w2;
      if (have_build) {
        const double dx = px[i] - Bx[i], dy = py[i] - By[i], dz = pz[i] - Bz[i];
        const double d2 = dx * dx + dy * dy + dz * dz;
        m2 = m2 > d2 ? m2 : d2;
      }
    }
    if (!orientation) return have_build ? std::sqrt(m2) : 1e300;
    double *qw = st.qw.data(), *qx = st.qx.data(), *qy = st.qy.data(), *qz = st.qz.data();
    if (phys::small_rotation(w2max, dt)) {
#pragma omp parallel for simd num_threads(nt()) schedule(static)
      for (std::int64_t i = 0; i < sn; ++i) {
        double q0 = qw[i], q1 = qx[i], q2 = qy[i], q3 = qz[i];  // registers, not memory
        phys::rotate_quaternion_small(q0, q1, q2, q3, wx[i], wy[i], wz[i], dt);
        qw[i] = q0, qx[i] = q1, qy[i] = q2, qz[i] = q3;
      }
    } else {
#pragma omp parallel for num_threads(nt()) schedule(static)
      for (std::int64_t i = 0; i < sn; ++i)
        phys::rotate_quaternion(qw[i], qx[i], qy[i], qz[i], wx[i], wy[i], wz[i], dt);
    }
    return have_build ? std::sqrt(m2) : 1e300;
  }

  void wall_reduce(bool last, ForceMode mode, std::int64_t substeps) {
    for (auto& w : walls) w.force = {0, 0, 0}, w.torque = {0, 0, 0};
    std::vector<double>& nodef = node_buf;  // member: no allocation per step
    if (has_flex) nodef.assign(flex.mesh.vertices.size(), 0.0);
    const std::size_t np = n();
    for (std::size_t i = 0; i < np; ++i)
      for (int c = 0; c < wcount[i]; ++c) {
        const std::size_t slot = kMaxWallContacts * i + c;
        const std::int32_t tri = wtri[slot];
        const std::int32_t w = tri_wall[tri];
        // force ON the wall = - force on the particle
        const Vec3 f{-wf[3 * slot], -wf[3 * slot + 1], -wf[3 * slot + 2]};
        if (w >= 0) {
          const Vec3 x{wp[3 * slot], wp[3 * slot + 1], wp[3 * slot + 2]};
          const Vec3 q = phys::cross(x, f);
          auto& W = walls[w];
          W.force[0] += f.x, W.force[1] += f.y, W.force[2] += f.z;
          W.torque[0] += q.x, W.torque[1] += q.y, W.torque[2] += q.z;
        } else {
          for (int e = 0; e < 3; ++e) {
            const std::int64_t node = tri_v[3 * tri + e] - flex.vbase;
            const Vec3 fb = phys::node_share(wb[3 * slot + e], f);
            nodef[3 * node] += fb.x, nodef[3 * node + 1] += fb.y, nodef[3 * node + 2] += fb.z;
          }
        }
      }
    if (has_flex) {
      if (mode == ForceMode::average) {
        const double inv = 1.0 / static_cast<double>(substeps);
        for (std::size_t k = 0; k < nodef.size(); ++k) flex_force[k] += inv * nodef[k];
      } else if (last) {
        flex_force = nodef;
      }
    }
  }

  template <bool Friction>
  void step(bool last, ForceMode mode, std::int64_t substeps) {
    const double t0 = omp_get_wtime();
    const double disp = kick_drift<Friction>();
    if (!bodies.empty()) bodies.kick_drift(s.dt);
    t += s.dt;
    flex_tau += s.dt;
    double wdisp = 0.0;
    if (walls_moving) {
      update_walls(t, flex_tau);
      wdisp = wall_displacement();
    }
    const double t1 = omp_get_wtime();
    // Build when the candidates may miss a pair that comes within skin_in (d_i + d_j since
    // the build > skin - skin_in) or a wall; refilter when a pair outside the list may touch
    // (d_i + d_j since the last update > skin_in). d_i + d_j is bounded by twice the largest
    // displacement, and when that bound calls for an update, by the sum of the two largest
    // (a pass over the particles): a few fast spheres in a resting bed then use the whole
    // skin before they call for a build, instead of half of it.
    const double dbuild = out_disp + disp;   // |x - x_build| <= sum of the refilter intervals
    const bool one_level = skin_in >= skin;  // the list is the build's: no refilter
    // the pair parts of the rules, for a bound pd of d_i + d_j since the last update
    auto build_by_pairs = [&](double pd) {
      return one_level ? pd > skin : out_pair + pd > skin - skin_in;
    };
    auto refilter_by_pairs = [&](double pd) { return !one_level && pd > skin_in; };
    double pdisp = 2.0 * disp;
    if (!need_rebuild && disp < 1e300 && (build_by_pairs(pdisp) || refilter_by_pairs(pdisp)))
      pdisp = two_largest_displacements();
    const double pbuild = out_pair + pdisp;  // d_i + d_j since the build, any pair
    // (one level: no refilter has added to out_disp since the build, so dbuild = disp)
    if (need_rebuild || build_by_pairs(pdisp) || dbuild + wdisp > skin) {
      rebuild();
    } else if (refilter_by_pairs(pdisp)) {
      if (adapt_inner_skin(false, pbuild)) {
        out_disp += disp;
        out_pair += pdisp;
        refilter();
      } else {
        rebuild();
      }
    }
    const double t2 = omp_get_wtime();
    if (poly)
      forces_and_kick<Friction, true>();
    else
      forces_and_kick<Friction>();
    // Wall forces and torques are read after advance(): summed at its last step only. The
    // flexible mesh's node forces are summed every substep when they are averaged, and the
    // rigid bodies' loads every substep (they move by them).
    if (!tri_v.empty() && (last || (has_flex && mode == ForceMode::average) || !bodies.empty()))
      wall_reduce(last, mode, substeps);
    if (!bodies.empty()) {
      for (const auto& w : walls)
        if (w.body >= 0) bodies.set_loads(w.body, w.force, w.torque);
      bodies.kick(s.dt);
    }
    ++steps;
    const double t3 = omp_get_wtime();
    timing.integration += t1 - t0;
    timing.detection += t2 - t1;
    timing.forces += t3 - t2;
  }

  // Wall kinematics for the device (filled by gpu_wall_kinematics() when walls move): the
  // reference vertices (rigid walls) and the node positions at the start of the advance()
  // (flexible mesh) in store order, the wall of each vertex (-1: flexible).
  std::vector<double> gpu_vref;
  std::vector<std::int32_t> gpu_vwall;

  void gpu_wall_kinematics() {
    gpu_vref.assign(vpos.size(), 0.0);
    gpu_vwall.assign(vpos.size() / 3, -1);
    for (std::size_t w = 0; w < walls.size(); ++w) {
      const auto& x0 = walls[w].mesh.vertices;
      std::copy(x0.begin(), x0.end(), gpu_vref.begin() + 3 * walls[w].vbase);
      std::fill_n(gpu_vwall.begin() + walls[w].vbase, x0.size() / 3, static_cast<std::int32_t>(w));
    }
    if (has_flex) std::copy(flex_x.begin(), flex_x.end(), gpu_vref.begin() + 3 * flex.vbase);
  }

  GpuHostView gpu_view() {
    GpuHostView v;
    v.n = n();
    v.px = st.px.data(), v.py = st.py.data(), v.pz = st.pz.data();
    v.vx = st.vx.data(), v.vy = st.vy.data(), v.vz = st.vz.data();
    v.wx = st.wx.data(), v.wy = st.wy.data(), v.wz = st.wz.data();
    v.qw = st.qw.data(), v.qx = st.qx.data(), v.qy = st.qy.data(), v.qz = st.qz.data();
    v.fx = st.fx.data(), v.fy = st.fy.data(), v.fz = st.fz.data();
    v.tx = tx.data(), v.ty = ty.data(), v.tz = tz.data();
    v.radius = st.radius.data(), v.mass = st.mass.data(), v.inertia = st.inertia.data();
    v.material = st.material.data();
    v.npairs = nbr.size();
    v.row = row.data(), v.trow = trow.data(), v.tpair = tpair.data(), v.nbr = nbr.data();
    v.shear = shear.data();
    v.rhist = rolling ? rhist.data() : nullptr;
    v.bx = bx.data(), v.by = by.data(), v.bz = bz.data();
    v.pc = pc.data();
    v.nmat = nmat;
    v.dt = s.dt;
    for (int k = 0; k < 3; ++k) v.gravity[k] = s.gravity[k];
    v.friction = friction, v.rolling = rolling;
    v.orientation = orientation;
    if (poly) {
      const auto& a = shapes.arrays();
      v.poly = true;
      v.nshapes = a.nv.size(), v.nshape_verts = a.vert.size() / 3;
      v.nshape_faces = a.flen.size(), v.nshape_fverts = a.fvert.size();
      v.nshape_edges = a.edge.size() / 2;
      v.vbase = a.vbase.data(), v.snv = a.nv.data(), v.fbase = a.fbase.data(), v.snf = a.nf.data();
      v.floop = a.floop.data(), v.flen = a.flen.data(), v.fvert = a.fvert.data();
      v.ebase = a.ebase.data(), v.sne = a.ne.data(), v.edge = a.edge.data();
      v.vert = a.vert.data(), v.fnormal = a.fnormal.data(), v.dilation = a.dilation.data();
      v.bound = a.bound.data();
      v.shape_id = st.shape_id.data(), v.scale = st.scale.data();
      v.ix = st.ix.data(), v.iy = st.iy.data(), v.iz = st.iz.data();
      v.ptj = ptj.data(), v.paxis = paxis.data(), v.pfeat = pfeat.data();
    }
    if (!tri_v.empty()) {
      v.nverts = vpos.size() / 3, v.ntris = tri_v.size() / 3, v.nptri = ptri.size();
      v.vpos = vpos.data(), v.vvel = vvel.data();
      v.tri_v = tri_v.data(), v.tri_e = tri_e.data(), v.tri_mat = tri_mat.data();
      v.tri_wall = tri_wall.data(), v.prow = prow.data(), v.ptri = ptri.data();
      v.wkey = wkey.data(), v.wshear = wshear.data(), v.wf = wf.data(), v.wp = wp.data();
      v.wb = wb.data(), v.wtri = wtri.data(), v.wcount = wcount.data();
      if (walls_moving) {
        v.walls_moving = true;
        v.vbuild = vbuild.data(), v.vref = gpu_vref.data(), v.vwall = gpu_vwall.data();
        v.motion = wall_motions.data(), v.nwalls = wall_motions.size();
        if (has_flex) {
          v.flex_vbase = static_cast<std::size_t>(flex.vbase), v.flex_nodes = flex_x.size() / 3;
          v.flex_v = flex_v.data(), v.flex_a = flex_a.data(), v.flex_force = flex_force.data();
        }
      }
      v.wroll = rolling ? wroll.data() : nullptr;
    }
    return v;
  }

  // CUDA backend: the same step on the device; the neighbour list is built here (host) when
  // the device reports that it must be (the CPU rule, moving walls included). Moving walls
  // and the flexible mesh are placed on the device every step by the CPU's formulas
  // (physics/wall_motion.hpp); the device sums the flexible node forces as `mode` asks.
  void advance_gpu(std::int64_t substeps, ForceMode mode) {
    const double t0 = omp_get_wtime();
    if (has_flex) {
      std::fill(flex_force.begin(), flex_force.end(), 0.0);
      flex_max_ov = 0.0;
    }
    if (n() == 0) {  // nothing for the device: the CPU step moves the walls and the clock
      for (std::int64_t k = 0; k < substeps; ++k)
        friction ? step<true>(k + 1 == substeps, mode, substeps)
                 : step<false>(k + 1 == substeps, mode, substeps);
      return;
    }
    if (need_rebuild || row.size() != n() + 1 || bx.size() != n()) rebuild();
    if (walls_moving) gpu_wall_kinematics();
    auto view = [&] {
      GpuHostView v = gpu_view();
      v.flex_average = mode == ForceMode::average;
      v.flex_inv_substeps = 1.0 / static_cast<double>(substeps);
      return v;
    };
    cuda_upload_state(gpu, view());
    cuda_upload_lists(gpu, view());
    std::int64_t left = substeps;
    double tdet = 0.0;
    while (left > 0) {
      const std::int64_t done = cuda_run_steps(gpu, left, skin, t, flex_tau, cancel);
      for (std::int64_t k = 0; k < done; ++k) t += s.dt, flex_tau += s.dt;  // the device's sums
      steps += done;
      left -= done;
      check_cancel(substeps - left, substeps);
      if (left > 0) {  // drift of the next step done, forces wait for the new list
        const double r0 = omp_get_wtime();
        cuda_download_state(gpu, view());  // with the moved walls
        rebuild();
        cuda_upload_lists(gpu, view());
        tdet += omp_get_wtime() - r0;
        cuda_finish_step(gpu);
        t += s.dt, flex_tau += s.dt;
        ++steps;
        --left;
      }
    }
    cuda_download_state(gpu, view());
    max_ov = cuda_max_overlap(gpu);
    adv_max_ov = cuda_advance_max_overlap(gpu);
    if (has_flex) flex_max_ov = cuda_flex_max_overlap(gpu);
    if (walls_moving && tri_v.empty()) update_walls(t, flex_tau);  // no triangle on the device
    // Per-wall force and torque of the last step from its contact slots, in the CPU's order
    // (last = false: the flexible node forces came from the device).
    if (!tri_v.empty()) wall_reduce(false, ForceMode::last_substep, 1);
    timing.detection += tdet;
    timing.forces += omp_get_wtime() - t0 - tdet;  // device steps are not split further
  }

  void refresh_particle_derived() {
    rmax = 0.0;
    for (double r : st.radius) rmax = std::max(rmax, r);
    skin = s.skin > 0.0 ? s.skin : 0.2 * rmax;
    orientation = s.track_orientation;
    poly_count = 0;
    for (std::uint8_t shape : st.shape)
      poly_count += shape != static_cast<std::uint8_t>(ParticleShape::sphere) ? 1 : 0;
    poly = poly_count > 0;
    orientation = orientation || poly;
    // The CUDA backend checks the list against the whole skin on the device: one level.
    skin_in = gpu != nullptr ? skin : (s.list_skin > 0.0 ? s.list_skin : kInnerSkin) * skin;
  }
};

// =========================================================================================
DemSystem::DemSystem(DemSettings settings) : impl_(std::make_unique<Impl>()) {
  validate(settings);
  impl_->s = std::move(settings);
  impl_->threads = impl_->s.threads > 0 ? impl_->s.threads : omp_get_max_threads();
  impl_->setup_pairs();
  if (impl_->s.backend == "cuda") {
    if (!cuda_available())
      throw std::runtime_error(
          "DemSystem: settings.backend = 'cuda' but this build has no CUDA backend or no CUDA "
          "device is present; use backend = 'cpu'");
    impl_->gpu = cuda_backend_create();
  }
}
DemSystem::~DemSystem() = default;
DemSystem::DemSystem(DemSystem&&) noexcept = default;
DemSystem& DemSystem::operator=(DemSystem&&) noexcept = default;

const DemSettings& DemSystem::settings() const {
  return impl_->s;
}

std::int32_t DemSystem::add_shape(const PolyhedronShape& shape) {
  return impl_->shapes.add(shape);
}
std::size_t DemSystem::shape_count() const {
  return impl_->shapes.size();
}
const PolyhedronShape& DemSystem::shape(std::int32_t id) const {
  if (id < 0 || static_cast<std::size_t>(id) >= impl_->shapes.size())
    throw std::out_of_range("DemSystem: shape index " + std::to_string(id) + " outside [0, " +
                            std::to_string(impl_->shapes.size()) + ")");
  return impl_->shapes.shape(id);
}

std::size_t DemSystem::add_particles(std::span<const ParticleInit> particles) {
  auto& I = *impl_;
  auto& st = I.st;
  const std::size_t first = st.size();
  for (std::size_t k = 0; k < particles.size(); ++k) {
    const auto& p = particles[k];
    const std::string where = "add_particles: particle " + std::to_string(k);
    if (!finite3(p.position) || !finite3(p.velocity) || !finite3(p.angular_velocity))
      bad(where + " has a non-finite position, velocity or angular velocity");
    if (p.shape == ParticleShape::sphere && (!(p.radius > 0.0) || !std::isfinite(p.radius)))
      bad(where + ".radius = " + std::to_string(p.radius) + " must be > 0 m");
    if (p.material < 0 || static_cast<std::size_t>(p.material) >= I.nmat)
      bad(where + ".material = " + std::to_string(p.material) + " outside [0, " +
          std::to_string(I.nmat) + ")");
    if (!(I.s.materials[p.material].density > 0.0))
      bad(where + ": material '" + I.s.materials[p.material].name +
          "' has density 0 (particles need a density > 0)");
    if (p.shape == ParticleShape::polyhedron) {
      if (p.shape_id < 0 || static_cast<std::size_t>(p.shape_id) >= I.shapes.size())
        bad(where + ".shape_id = " + std::to_string(p.shape_id) + " outside [0, " +
            std::to_string(I.shapes.size()) + ") (add_shape first)");
      if (!(p.scale > 0.0) || !std::isfinite(p.scale))
        bad(where + ".scale = " + std::to_string(p.scale) + " must be > 0");
    } else if (p.shape != ParticleShape::sphere) {
      bad(where + ".shape = " + std::to_string(static_cast<int>(p.shape)) +
          " is not a shape (sphere 0, polyhedron 1)");
    }
    const auto& q = p.orientation;
    const double q2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (!(std::abs(q2 - 1.0) <= 1e-6))
      bad(where + ".orientation is not a unit quaternion (|q|^2 = " + std::to_string(q2) +
          ", accepted 1 +- 1e-6)");
  }
  for (const auto& p : particles) {
    st.px.push_back(p.position[0]), st.py.push_back(p.position[1]), st.pz.push_back(p.position[2]);
    st.vx.push_back(p.velocity[0]), st.vy.push_back(p.velocity[1]), st.vz.push_back(p.velocity[2]);
    st.wx.push_back(p.angular_velocity[0]), st.wy.push_back(p.angular_velocity[1]),
        st.wz.push_back(p.angular_velocity[2]);
    const auto& q0 = p.orientation;
    const double ql =
        std::sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3]);
    if (ql == 1.0)  // keep the bits of a unit quaternion as given
      st.qw.push_back(q0[0]), st.qx.push_back(q0[1]), st.qy.push_back(q0[2]),
          st.qz.push_back(q0[3]);
    else
      st.qw.push_back(q0[0] / ql), st.qx.push_back(q0[1] / ql), st.qy.push_back(q0[2] / ql),
          st.qz.push_back(q0[3] / ql);
    const double rho = I.s.materials[p.material].density;
    double m, radius, inertia;
    std::array<double, 3> ib;
    if (p.shape == ParticleShape::polyhedron) {
      // the shape at scale s: volume s^3, inertia s^5 (principal frame), bounding radius s
      const PolyhedronShape& sh = I.shapes.shape(p.shape_id);
      const double sc = p.scale;
      m = rho * sc * sc * sc * sh.volume;
      const double s5 = rho * sc * sc * sc * sc * sc;
      ib = {s5 * sh.inertia[0], s5 * sh.inertia[1], s5 * sh.inertia[2]};
      radius = sc * I.shapes.bound(p.shape_id);
      inertia = (ib[0] + ib[1] + ib[2]) / 3.0;
      st.shape_id.push_back(p.shape_id), st.scale.push_back(sc);
    } else {
      m = rho * 4.0 / 3.0 * 3.14159265358979323846 * p.radius * p.radius * p.radius;
      radius = p.radius;
      inertia = 0.4 * m * p.radius * p.radius;
      ib = {inertia, inertia, inertia};
      st.shape_id.push_back(-1), st.scale.push_back(1.0);
    }
    st.ix.push_back(ib[0]), st.iy.push_back(ib[1]), st.iz.push_back(ib[2]);
    st.fx.push_back(m * I.s.gravity[0]), st.fy.push_back(m * I.s.gravity[1]),
        st.fz.push_back(m * I.s.gravity[2]);
    st.radius.push_back(radius), st.mass.push_back(m), st.inertia.push_back(inertia);
    st.material.push_back(p.material);
    st.shape.push_back(static_cast<std::uint8_t>(p.shape));
    I.tx.push_back(0), I.ty.push_back(0), I.tz.push_back(0);
  }
  const std::size_t n = st.size();
  I.wkey.resize(kMaxWallContacts * n, -1);
  I.wshear.resize(3 * kMaxWallContacts * n, 0.0);
  if (I.rolling) I.wroll.resize(3 * kMaxWallContacts * n, 0.0);
  I.wf.resize(3 * kMaxWallContacts * n), I.wp.resize(3 * kMaxWallContacts * n),
      I.wb.resize(3 * kMaxWallContacts * n), I.wtri.resize(kMaxWallContacts * n);
  I.wcount.resize(n, 0);
  // keep the pair rows of the old particles (new ones have none yet)
  if (!I.row.empty()) I.row.resize(n + 1, I.row.back());
  I.bx.clear();
  I.refresh_particle_derived();
  I.need_rebuild = true;
  return first;
}

void DemSystem::remove_particles(std::span<const std::uint8_t> keep) {
  auto& I = *impl_;
  const std::size_t n = I.n();
  if (keep.size() != n)
    bad("remove_particles: keep has " + std::to_string(keep.size()) + " entries, need " +
        std::to_string(n));
  std::vector<std::int32_t> map(n, -1);
  std::int32_t m = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (keep[i]) map[i] = m++;
  auto compact = [&](auto& v, std::size_t stride) {
    std::size_t o = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (keep[i]) {
        for (std::size_t d = 0; d < stride; ++d) v[stride * o + d] = v[stride * i + d];
        ++o;
      }
    v.resize(stride * o);
  };
  // pair rows: renumber, drop pairs with a removed particle (order i < j is kept)
  if (I.row.size() == n + 1) {
    std::vector<std::int64_t> nrow(static_cast<std::size_t>(m) + 1, 0);
    std::vector<std::int32_t> nnbr;
    std::vector<double> nsh, nrh, nax;
    std::vector<std::int32_t> nft;
    for (std::size_t i = 0; i < n; ++i) {
      if (!keep[i]) continue;
      for (std::int64_t p = I.row[i]; p < I.row[i + 1]; ++p) {
        if (map[I.nbr[p]] < 0) continue;
        nnbr.push_back(map[I.nbr[p]]);
        if (!I.shear.empty())
          for (int d = 0; d < 3; ++d) nsh.push_back(I.shear[3 * p + d]);
        if (!I.rhist.empty())
          for (int d = 0; d < 3; ++d) nrh.push_back(I.rhist[3 * p + d]);
        if (!I.paxis.empty())
          for (int d = 0; d < 3; ++d) nax.push_back(I.paxis[3 * p + d]);
        if (!I.pfeat.empty())
          for (int d = 0; d < 6; ++d) nft.push_back(I.pfeat[6 * p + d]);
      }
      nrow[map[i] + 1] = static_cast<std::int64_t>(nnbr.size());
    }
    I.row.swap(nrow), I.nbr.swap(nnbr), I.shear.swap(nsh), I.rhist.swap(nrh);
    I.paxis.swap(nax);
    I.pfeat.swap(nft);
  }
  auto& st = I.st;
  for (auto* v : {&st.px,     &st.py,   &st.pz,      &st.vx, &st.vy, &st.vz, &st.wx, &st.wy,
                  &st.wz,     &st.qw,   &st.qx,      &st.qy, &st.qz, &st.fx, &st.fy, &st.fz,
                  &st.radius, &st.mass, &st.inertia, &I.tx,  &I.ty,  &I.tz,  &st.scale,
                  &st.ix,     &st.iy,   &st.iz})
    compact(*v, 1);
  compact(st.material, 1);
  compact(st.shape, 1);
  compact(st.shape_id, 1);
  compact(I.wkey, kMaxWallContacts), compact(I.wshear, 3 * kMaxWallContacts);
  if (!I.wroll.empty()) compact(I.wroll, 3 * kMaxWallContacts);
  compact(I.wf, 3 * kMaxWallContacts), compact(I.wp, 3 * kMaxWallContacts),
      compact(I.wb, 3 * kMaxWallContacts), compact(I.wtri, kMaxWallContacts);
  compact(I.wcount, 1);
  I.bx.clear();
  I.refresh_particle_derived();
  I.need_rebuild = true;
}

const ParticleState& DemSystem::particles() const {
  return impl_->st;
}
std::size_t DemSystem::particle_count() const {
  return impl_->n();
}

std::int32_t DemSystem::add_wall(WallMesh wall) {
  auto& I = *impl_;
  const std::string where = "add_wall('" + wall.name + "')";
  if (wall.vertices.size() % 3 != 0) bad(where + ": vertices size is not a multiple of 3");
  if (wall.triangles.size() % 3 != 0) bad(where + ": triangles size is not a multiple of 3");
  for (double x : wall.vertices)
    if (!std::isfinite(x)) bad(where + ": non-finite vertex coordinate");
  const auto nv = static_cast<std::int32_t>(wall.vertices.size() / 3);
  for (auto t : wall.triangles)
    if (t < 0 || t >= nv)
      bad(where + ": triangle vertex index " + std::to_string(t) + " outside [0, " +
          std::to_string(nv) + ")");
  if (wall.material < 0 || static_cast<std::size_t>(wall.material) >= I.nmat)
    bad(where + ": material " + std::to_string(wall.material) + " outside [0, " +
        std::to_string(I.nmat) + ")");
  const auto& m = wall.motion;
  if (!(m.end_time >= m.start_time)) bad(where + ": motion.end_time < motion.start_time");
  if (m.kind == WallMotion::Kind::rotation || m.kind == WallMotion::Kind::sinusoid) {
    const double a =
        std::sqrt(m.axis[0] * m.axis[0] + m.axis[1] * m.axis[1] + m.axis[2] * m.axis[2]);
    if (!(a > 0.0)) bad(where + ": motion.axis must be non-zero");
    if (m.kind == WallMotion::Kind::sinusoid)
      for (double& c : wall.motion.axis) c /= a;
  }
  Impl::Wall w;
  if (wall.body.enabled) {
    if (I.gpu != nullptr || I.s.backend != "cpu")
      bad(where +
          ": rigid bodies moved by contact forces run on the CPU backend only (the CUDA "
          "backend has no kernel for them yet)");
    w.body = I.bodies.add(wall, I.s.gravity, where);
  }
  w.mesh = std::move(wall);
  I.walls.push_back(std::move(w));
  I.build_wall_store();
  I.update_walls(I.t, I.flex_tau);
  I.vbuild = I.vpos;
  return static_cast<std::int32_t>(I.walls.size() - 1);
}

std::size_t DemSystem::wall_count() const {
  return impl_->walls.size();
}

#define check_wall(I, wall)                                                                   \
  if ((wall) < 0 || static_cast<std::size_t>(wall) >= (I).walls.size())                       \
  throw std::out_of_range("DemSystem: wall index " + std::to_string(wall) + " outside [0, " + \
                          std::to_string((I).walls.size()) + ")")

std::array<double, 3> DemSystem::wall_force(std::int32_t wall) const {
  check_wall(*impl_, wall);
  return impl_->walls[wall].force;
}
WallFaceLoad DemSystem::wall_face_load(std::int32_t wall,
                                       const std::array<double, 3>& direction) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls[wall];
  const double dl = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                              direction[2] * direction[2]);
  if (!(dl > 0)) bad("wall_face_load: direction must not be zero");
  const Vec3 d{direction[0] / dl, direction[1] / dl, direction[2] / dl};
  auto vertex = [&I](std::int64_t v) {
    return Vec3{I.vpos[3 * v], I.vpos[3 * v + 1], I.vpos[3 * v + 2]};
  };
  const auto nv = static_cast<std::int64_t>(w.mesh.vertices.size() / 3);
  const auto nt = static_cast<std::int64_t>(w.mesh.triangles.size() / 3);
  Vec3 c{0, 0, 0};
  for (std::int64_t v = 0; v < nv; ++v) c = c + vertex(w.vbase + v);
  c = (1.0 / static_cast<double>(nv)) * c;
  // The face: triangles normal to `direction` (either winding) on its side of the centroid.
  std::vector<std::uint8_t> on_face(static_cast<std::size_t>(nt), 0);
  WallFaceLoad load;
  for (std::int64_t k = 0; k < nt; ++k) {
    const std::int64_t t = w.tbase + k;
    const Vec3 a = vertex(I.tri_v[3 * t]), b = vertex(I.tri_v[3 * t + 1]),
               e = vertex(I.tri_v[3 * t + 2]);
    const Vec3 n = phys::cross(b - a, e - a);
    const double ln = std::sqrt(phys::dot(n, n));
    const Vec3 g = (1.0 / 3.0) * (a + b + e);
    const bool face =
        ln > 0 && std::abs(phys::dot(n, d)) > (1.0 - 1e-6) * ln && phys::dot(g - c, d) > 0;
    on_face[static_cast<std::size_t>(k)] = face;
    if (face) load.area += 0.5 * ln;
  }
  auto& f = load.force;
  for (std::size_t i = 0; i < I.n(); ++i)
    for (int k = 0; k < I.wcount[i]; ++k) {
      const std::size_t slot = kMaxWallContacts * i + k;
      const std::int64_t t = I.wtri[slot] - w.tbase;
      if (t < 0 || t >= nt || !on_face[static_cast<std::size_t>(t)]) continue;
      // force ON the wall; a contact at the face's edge that pulls it outwards (a particle
      // beside the wall, below the face's plane) is not a load on the face
      const Vec3 fw{-I.wf[3 * slot], -I.wf[3 * slot + 1], -I.wf[3 * slot + 2]};
      if (phys::dot(fw, d) > 0) continue;
      f[0] += fw.x, f[1] += fw.y, f[2] += fw.z;
    }
  return load;
}
std::array<double, 3> DemSystem::wall_torque(std::int32_t wall) const {
  check_wall(*impl_, wall);
  return impl_->walls[wall].torque;
}
std::vector<double> DemSystem::wall_vertices(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& I = *impl_;
  const auto& w = I.walls[wall];
  return {I.vpos.begin() + 3 * w.vbase, I.vpos.begin() + 3 * w.vbase + w.mesh.vertices.size()};
}

RigidBodyState DemSystem::body_state(std::int32_t wall) const {
  check_wall(*impl_, wall);
  const auto& w = impl_->walls[wall];
  if (w.body < 0)
    throw std::invalid_argument("DemSystem: wall " + std::to_string(wall) + " (" + w.mesh.name +
                                ") is not a rigid body");
  return impl_->bodies.state(w.body);
}

void DemSystem::set_flexible_mesh(const InterfaceMesh& mesh, std::int32_t material) {
  auto& I = *impl_;
  const auto nv = static_cast<std::int32_t>(mesh.node_count());
  if (mesh.reference_positions.size() % 3 != 0 || mesh.triangles.size() % 3 != 0)
    bad("set_flexible_mesh: array sizes are not multiples of 3");
  for (auto t : mesh.triangles)
    if (t < 0 || t >= nv)
      bad("set_flexible_mesh: node index " + std::to_string(t) + " outside [0, " +
          std::to_string(nv) + ")");
  if (material < 0 || static_cast<std::size_t>(material) >= I.nmat)
    bad("set_flexible_mesh: material " + std::to_string(material) + " outside [0, " +
        std::to_string(I.nmat) + ")");
  I.flex = {};
  I.flex.mesh.name = "flexible";
  I.flex.mesh.vertices = mesh.reference_positions;
  I.flex.mesh.triangles = mesh.triangles;
  I.flex.mesh.material = material;
  I.flex.flexible = true;
  I.has_flex = true;
  I.flex_x = mesh.reference_positions;
  I.flex_v.assign(I.flex_x.size(), 0.0);
  I.flex_a.assign(I.flex_x.size(), 0.0);
  I.flex_force.assign(I.flex_x.size(), 0.0);
  I.flex_tau = 0.0;
  I.build_wall_store();
  I.update_walls(I.t, 0.0);
  I.vbuild = I.vpos;
}

bool DemSystem::has_flexible_mesh() const {
  return impl_->has_flex;
}

void DemSystem::set_flexible_kinematics(std::span<const double> positions,
                                        std::span<const double> velocities,
                                        std::span<const double> accelerations) {
  auto& I = *impl_;
  if (!I.has_flex) bad("set_flexible_kinematics: no flexible mesh set");
  const std::size_t n3 = I.flex_x.size();
  if (positions.size() != n3 || velocities.size() != n3 || accelerations.size() != n3)
    bad("set_flexible_kinematics: arrays must have 3 * node_count = " + std::to_string(n3) +
        " entries");
  for (std::size_t k = 0; k < n3; ++k)
    if (!std::isfinite(positions[k]) || !std::isfinite(velocities[k]) ||
        !std::isfinite(accelerations[k]))
      bad("set_flexible_kinematics: non-finite value at entry " + std::to_string(k));
  I.flex_x.assign(positions.begin(), positions.end());
  I.flex_v.assign(velocities.begin(), velocities.end());
  I.flex_a.assign(accelerations.begin(), accelerations.end());
  I.flex_tau = 0.0;
  I.update_walls(I.t, 0.0);
}

void DemSystem::flexible_forces(std::span<double> forces) const {
  const auto& I = *impl_;
  if (!I.has_flex) bad("flexible_forces: no flexible mesh set");
  if (forces.size() != I.flex_force.size())
    bad("flexible_forces: output must have 3 * node_count = " +
        std::to_string(I.flex_force.size()) + " entries");
  std::copy(I.flex_force.begin(), I.flex_force.end(), forces.begin());
}

std::vector<double> DemSystem::flexible_positions() const {
  const auto& I = *impl_;
  if (!I.has_flex) return {};
  return {I.vpos.begin() + 3 * I.flex.vbase, I.vpos.begin() + 3 * I.flex.vbase + I.flex_x.size()};
}

double DemSystem::flexible_max_overlap() const {
  return impl_->flex_max_ov;
}

void DemSystem::advance(std::int64_t substeps, ForceMode mode) {
  auto& I = *impl_;
  if (substeps < 0) bad("advance: substeps = " + std::to_string(substeps) + " must be >= 0");
  if (substeps == 0) return;
  I.adv_max_ov = 0.0;
  if (I.gpu) {
    I.advance_gpu(substeps, mode);
    return;
  }
  if (I.has_flex) {
    std::fill(I.flex_force.begin(), I.flex_force.end(), 0.0);
    I.flex_max_ov = 0.0;
  }
  for (std::int64_t k = 0; k < substeps; ++k) {
    I.check_cancel(k, substeps);
    const bool last = k + 1 == substeps;
    if (I.friction)
      I.step<true>(last, mode, substeps);
    else
      I.step<false>(last, mode, substeps);
  }
}

void DemSystem::set_cancel_flag(const std::atomic<bool>* flag) {
  impl_->cancel = flag;
}

double DemSystem::advance_max_overlap() const {
  return impl_->adv_max_ov;
}
double DemSystem::time() const {
  return impl_->t;
}
std::int64_t DemSystem::step_count() const {
  return impl_->steps;
}

double DemSystem::smallest_contact_radius() const {
  const auto& I = *impl_;
  double r = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < I.n(); ++i)
    r = std::min(r, I.st.shape_id[i] >= 0
                        ? I.st.scale[i] * I.shapes.shape(I.st.shape_id[i]).dilation
                        : I.st.radius[i]);
  return r;
}

double DemSystem::rayleigh_time_step() const {
  const auto& I = *impl_;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < I.n(); ++i) {
    const auto& m = I.s.materials[I.st.material[i]];
    const double g = m.youngs_modulus / (2.0 * (1.0 + m.poisson_ratio));
    // a polyhedron: the radius of the sphere of its volume
    const double r = I.st.shape_id[i] >= 0
                         ? std::cbrt(3.0 * I.st.mass[i] / (4.0 * 3.14159265358979323846 * m.density))
                         : I.st.radius[i];
    best = std::min(best, phys::rayleigh_time_step(r, m.density, g, m.poisson_ratio));
  }
  return best;
}

double DemSystem::kinetic_energy() const {
  const auto& st = impl_->st;
  double e = 0.0;
  for (std::size_t i = 0; i < st.size(); ++i)
    if (st.shape_id[i] >= 0)
      e += 0.5 * st.mass[i] * (st.vx[i] * st.vx[i] + st.vy[i] * st.vy[i] + st.vz[i] * st.vz[i]) +
           phys::rotational_energy(phys::rotation(st.qw[i], st.qx[i], st.qy[i], st.qz[i]),
                                   Vec3{st.ix[i], st.iy[i], st.iz[i]},
                                   Vec3{st.wx[i], st.wy[i], st.wz[i]});
    else
      e += 0.5 * st.mass[i] * (st.vx[i] * st.vx[i] + st.vy[i] * st.vy[i] + st.vz[i] * st.vz[i]) +
           0.5 * st.inertia[i] * (st.wx[i] * st.wx[i] + st.wy[i] * st.wy[i] + st.wz[i] * st.wz[i]);
  return e;
}

double DemSystem::max_overlap() const {
  return impl_->max_ov;
}

DemSystem::Timings DemSystem::timings() const {
  return impl_->timing;
}

// Internal diagnostics for the benchmark and tests (declared in dem_system.hpp).
std::int64_t DemSystem::neighbour_rebuilds() const {
  return impl_->rebuilds;
}
std::int64_t DemSystem::neighbour_refilters() const {
  return impl_->refilters;
}
std::size_t DemSystem::neighbour_pairs() const {
  return impl_->nbr.size();
}
std::size_t DemSystem::contact_count() const {
  const auto& pf = impl_->pf;
  std::size_t c = 0;
  for (std::size_t p = 0; p + 2 < pf.size(); p += 3)
    if (pf[p] != 0.0 || pf[p + 1] != 0.0 || pf[p + 2] != 0.0) ++c;
  return c;
}
std::vector<std::int32_t> DemSystem::contact_counts() const {
  const auto& I = *impl_;
  std::vector<std::int32_t> n(I.st.size(), 0);
  for (std::size_t i = 0; i + 1 < I.row.size() && i < n.size(); ++i) {
    for (auto k = I.row[i]; k < I.row[i + 1]; ++k) {
      const auto p = static_cast<std::size_t>(3 * k);
      if (p + 2 < I.pf.size() && (I.pf[p] != 0.0 || I.pf[p + 1] != 0.0 || I.pf[p + 2] != 0.0)) {
        ++n[i];
        ++n[static_cast<std::size_t>(I.nbr[static_cast<std::size_t>(k)])];
      }
    }
  }
  return n;
}

std::size_t DemSystem::state_bytes() const {
  const auto& I = *impl_;
  const auto& st = I.st;
  std::size_t b = 0;
  auto add = [&b](const auto& v) { b += v.size() * sizeof(v[0]); };
  for (const auto* v : {&st.px, &st.py, &st.pz, &st.vx, &st.vy, &st.vz, &st.wx, &st.wy, &st.wz,
                        &st.qw, &st.qx, &st.qy, &st.qz, &st.fx, &st.fy, &st.fz, &st.radius,
                        &st.mass, &st.inertia, &st.scale, &st.ix, &st.iy, &st.iz, &I.tx, &I.ty,
                        &I.tz, &I.bx, &I.by, &I.bz})
    add(*v);
  add(st.material), add(st.shape), add(st.shape_id);
  add(I.row), add(I.nbr), add(I.pown), add(I.trow), add(I.tpair), add(I.tsrc);
  add(I.gather_row), add(I.gather_pair), add(I.gather_sign), add(I.shear), add(I.rhist);
  add(I.pf), add(I.pt), add(I.pr), add(I.ptj), add(I.paxis), add(I.pfeat), add(I.prot), add(I.orow),
      add(I.onbr);
  add(I.prow), add(I.ptri), add(I.wkey), add(I.wshear), add(I.wroll), add(I.wf), add(I.wp);
  add(I.wb), add(I.wtri), add(I.wcount);
  const auto& a = I.shapes.arrays();
  add(a.vert), add(a.fnormal), add(a.fvert), add(a.edge), add(a.floop), add(a.flen);
  add(a.vsoa), add(a.fsoa);
  return b;
}

// ---------------------------------------------------------------------------------------
namespace {
template <class T>
std::vector<std::int64_t> to64(const std::vector<T>& v) {
  return {v.begin(), v.end()};
}
template <class T>
std::vector<T> from64(const std::vector<std::int64_t>& v) {
  std::vector<T> o(v.size());
  for (std::size_t k = 0; k < v.size(); ++k) o[k] = static_cast<T>(v[k]);
  return o;
}
}  // namespace

// Every double array of the saved state with its dataset name: one list serves save() and
// restore(), so the two cannot drift apart. ImplT is Impl or const Impl.
template <class ImplT>
auto double_arrays(ImplT& I) {
  using Vec =
      std::conditional_t<std::is_const_v<ImplT>, const std::vector<double>, std::vector<double>>;
  auto& st = I.st;
  return std::array<std::pair<const char*, Vec*>, 39>{{{"px", &st.px},
                                                       {"py", &st.py},
                                                       {"pz", &st.pz},
                                                       {"vx", &st.vx},
                                                       {"vy", &st.vy},
                                                       {"vz", &st.vz},
                                                       {"wx", &st.wx},
                                                       {"wy", &st.wy},
                                                       {"wz", &st.wz},
                                                       {"qw", &st.qw},
                                                       {"qx", &st.qx},
                                                       {"qy", &st.qy},
                                                       {"qz", &st.qz},
                                                       {"fx", &st.fx},
                                                       {"fy", &st.fy},
                                                       {"fz", &st.fz},
                                                       {"radius", &st.radius},
                                                       {"mass", &st.mass},
                                                       {"inertia", &st.inertia},
                                                       {"tx", &I.tx},
                                                       {"ty", &I.ty},
                                                       {"tz", &I.tz},
                                                       {"shear", &I.shear},
                                                       {"rhist", &I.rhist},
                                                       {"wroll", &I.wroll},
                                                       {"bx", &I.bx},
                                                       {"by", &I.by},
                                                       {"bz", &I.bz},
                                                       {"wshear", &I.wshear},
                                                       {"vpos", &I.vpos},
                                                       {"vbuild", &I.vbuild},
                                                       {"flex_x", &I.flex_x},
                                                       {"flex_v", &I.flex_v},
                                                       {"flex_a", &I.flex_a},
                                                       {"flex_force", &I.flex_force},
                                                       {"scale", &st.scale},
                                                       {"ix", &st.ix},
                                                       {"iy", &st.iy},
                                                       {"iz", &st.iz}}};
}

namespace {
// The shape table: per shape its vertex and triangle counts, the concatenated vertices and
// triangles, dilation, volume and principal moments, and the names (one per line).
void save_shapes(const detail::ShapeTable& t, io::H5File& f, const std::string& g) {
  std::vector<std::int64_t> nv, ntri, tri;
  std::vector<double> vert, par;
  std::string names;
  for (std::size_t k = 0; k < t.size(); ++k) {
    const PolyhedronShape& s = t.shape(static_cast<std::int32_t>(k));
    nv.push_back(static_cast<std::int64_t>(s.vertices.size() / 3));
    ntri.push_back(static_cast<std::int64_t>(s.triangles.size() / 3));
    vert.insert(vert.end(), s.vertices.begin(), s.vertices.end());
    tri.insert(tri.end(), s.triangles.begin(), s.triangles.end());
    par.insert(par.end(), {s.dilation, s.volume, s.inertia[0], s.inertia[1], s.inertia[2]});
    names += s.name + "\n";
  }
  f.write(g + "shape_nv", std::span<const std::int64_t>(nv));
  f.write(g + "shape_ntri", std::span<const std::int64_t>(ntri));
  f.write(g + "shape_vertices", std::span<const double>(vert));
  f.write(g + "shape_triangles", std::span<const std::int64_t>(tri));
  f.write(g + "shape_params", std::span<const double>(par));
  f.set_attribute(g + "shape_nv", "names", names);
}

}  // namespace

std::vector<PolyhedronShape> read_state_shapes(const io::H5File& f, const std::string& group) {
  const std::string g = group + "/";
  std::vector<PolyhedronShape> out;
  if (!f.exists(g + "shape_nv")) return out;
  const auto nv = f.read_int64(g + "shape_nv"), ntri = f.read_int64(g + "shape_ntri");
  const auto vert = f.read_doubles(g + "shape_vertices");
  const auto tri = f.read_int64(g + "shape_triangles");
  const auto par = f.read_doubles(g + "shape_params");
  const std::string names = f.attribute_string(g + "shape_nv", "names");
  if (ntri.size() != nv.size() || par.size() != 5 * nv.size())
    throw std::invalid_argument("DemSystem: restore: inconsistent shape table in " +
                                f.path().string());
  std::size_t v0 = 0, t0 = 0, name0 = 0;
  for (std::size_t k = 0; k < nv.size(); ++k) {
    PolyhedronShape s;
    const std::size_t e = names.find('\n', name0);
    s.name = names.substr(name0, e == std::string::npos ? std::string::npos : e - name0);
    name0 = e == std::string::npos ? names.size() : e + 1;
    const auto vn = static_cast<std::size_t>(3 * nv[k]), tn = static_cast<std::size_t>(3 * ntri[k]);
    if (v0 + vn > vert.size() || t0 + tn > tri.size())
      throw std::invalid_argument("DemSystem: restore: inconsistent shape table in " +
                                  f.path().string());
    s.vertices.assign(vert.begin() + v0, vert.begin() + v0 + vn);
    for (std::size_t m = 0; m < tn; ++m) s.triangles.push_back(static_cast<std::int32_t>(tri[t0 + m]));
    s.dilation = par[5 * k], s.volume = par[5 * k + 1];
    s.inertia = {par[5 * k + 2], par[5 * k + 3], par[5 * k + 4]};
    v0 += vn, t0 += tn;
    out.push_back(std::move(s));
  }
  return out;
}

namespace {
// Replaces the table by the state's (a state without one keeps the system's).
void restore_shapes(detail::ShapeTable& t, const io::H5File& f, const std::string& g) {
  if (!f.exists(g + "shape_nv")) return;
  t.clear();
  for (const auto& s : read_state_shapes(f, g.substr(0, g.size() - 1))) t.add(s);
}
}  // namespace

void DemSystem::save(io::H5File& f, const std::string& group) const {
  const auto& I = *impl_;
  const auto& st = I.st;
  f.create_group(group);
  const std::string g = group + "/";
  f.set_attribute(group, "time", I.t);
  f.set_attribute(group, "steps", static_cast<std::int64_t>(I.steps));
  f.set_attribute(group, "flex_tau", I.flex_tau);
  f.set_attribute(group, "max_overlap", I.max_ov);
  f.set_attribute(group, "flex_max_overlap", I.flex_max_ov);
  f.set_attribute(group, "format", std::string("demfem-dem-state-1"));
  for (const auto& [name, v] : double_arrays(I)) f.write(g + name, std::span<const double>(*v));
  f.write(g + "material", std::span<const std::int64_t>(to64(st.material)));
  f.write(g + "shape", std::span<const std::uint8_t>(st.shape));
  f.write(g + "shape_id", std::span<const std::int64_t>(to64(st.shape_id)));
  save_shapes(I.shapes, f, g);
  f.write(g + "row", std::span<const std::int64_t>(I.row));
  f.write(g + "nbr", std::span<const std::int64_t>(to64(I.nbr)));
  f.write(g + "wkey", std::span<const std::int64_t>(I.wkey));
  f.write(g + "wcount", std::span<const std::uint8_t>(I.wcount));
  I.bodies.save(f, g);
}

namespace {
// Arrays of save() that a state copy within one coupling step leaves out: the particle
// properties do not change there, and the build positions are reset by the rebuild that
// follows restore_state().
bool constant_within_step(const char* name) {
  for (const char* c : {"radius", "mass", "inertia", "bx", "by", "bz"})
    if (std::strcmp(name, c) == 0) return true;
  return false;
}
}  // namespace

void DemSystem::save_state(DemStateCopy& c) const {
  const auto& I = *impl_;
  c.time = I.t;
  c.steps = I.steps;
  c.flex_tau = I.flex_tau;
  c.max_overlap = I.max_ov;
  c.flex_max_overlap = I.flex_max_ov;
  c.particles = I.n();
  const auto arrays = double_arrays(I);
  c.arrays.resize(arrays.size());
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    if (constant_within_step(arrays[k].first)) continue;
    c.arrays[k].assign(arrays[k].second->begin(), arrays[k].second->end());
  }
  c.row.assign(I.row.begin(), I.row.end());
  c.nbr.assign(I.nbr.begin(), I.nbr.end());
  c.wkey.assign(I.wkey.begin(), I.wkey.end());
  c.wcount.assign(I.wcount.begin(), I.wcount.end());
  c.bodies = I.bodies.pack();
}

void DemSystem::restore_state(const DemStateCopy& c) {
  auto& I = *impl_;
  if (c.steps < 0 || c.particles != I.n()) {
    throw std::logic_error("DemSystem::restore_state: " +
                           (c.steps < 0 ? std::string("nothing was saved")
                                        : "the state copy has " + std::to_string(c.particles) +
                                              " particles, the system " + std::to_string(I.n())));
  }
  I.t = c.time;
  I.steps = c.steps;
  I.flex_tau = c.flex_tau;
  I.max_ov = c.max_overlap;
  I.flex_max_ov = c.flex_max_overlap;
  const auto arrays = double_arrays(I);
  for (std::size_t k = 0; k < arrays.size(); ++k) {
    if (constant_within_step(arrays[k].first)) continue;
    arrays[k].second->assign(c.arrays[k].begin(), c.arrays[k].end());
  }
  I.row.assign(c.row.begin(), c.row.end());
  I.nbr.assign(c.nbr.begin(), c.nbr.end());
  I.wkey.assign(c.wkey.begin(), c.wkey.end());
  I.wcount.assign(c.wcount.begin(), c.wcount.end());
  if (!I.bodies.unpack(c.bodies))
    throw std::logic_error("DemSystem::restore_state: the state copy holds another number of "
                           "rigid bodies");
  // As restore(): the list is rebuilt from the restored positions and springs.
  I.bx.clear(), I.by.clear(), I.bz.clear();
  I.refresh_particle_derived();
  I.need_rebuild = true;
}

void DemSystem::restore(const io::H5File& f, const std::string& group) {
  auto& I = *impl_;
  auto& st = I.st;
  const std::string g = group + "/";
  if (!f.exists(group)) bad("restore: group '" + group + "' not found in " + f.path().string());
  const std::size_t nwalls = I.walls.size();
  I.t = f.attribute_double(group, "time");
  I.steps = f.attribute_int64(group, "steps");
  I.flex_tau = f.attribute_double(group, "flex_tau");
  I.max_ov = f.attribute_double(group, "max_overlap");
  I.flex_max_ov = f.attribute_double(group, "flex_max_overlap");
  for (const auto& [name, v] : double_arrays(I)) {
    // the rolling histories are absent in states written before the rolling spring model:
    // they then start at zero (checked against the pair list below)
    // so are the polyhedron arrays in states written before them (all spheres: set below)
    const bool optional = std::strcmp(name, "rhist") == 0 || std::strcmp(name, "wroll") == 0 ||
                          std::strcmp(name, "scale") == 0 || std::strcmp(name, "ix") == 0 ||
                          std::strcmp(name, "iy") == 0 || std::strcmp(name, "iz") == 0;
    *v = optional && !f.exists(g + name) ? std::vector<double>{} : f.read_doubles(g + name);
  }
  if (f.exists(g + "shape_id")) {
    st.shape_id = from64<std::int32_t>(f.read_int64(g + "shape_id"));
  } else {
    st.shape_id.assign(st.px.size(), -1);
    st.scale.assign(st.px.size(), 1.0);
    st.ix = st.iy = st.iz = st.inertia;
  }
  restore_shapes(I.shapes, f, g);
  st.material = from64<std::int32_t>(f.read_int64(g + "material"));
  st.shape = f.read_uint8(g + "shape");
  I.row = f.read_int64(g + "row");
  I.nbr = from64<std::int32_t>(f.read_int64(g + "nbr"));
  I.wkey = f.read_int64(g + "wkey");
  I.wcount = f.read_uint8(g + "wcount");
  try {
    I.bodies.restore(f, g);
  } catch (const std::invalid_argument& e) {
    bad(std::string("restore: ") + e.what());
  }
  const std::size_t n = st.px.size();
  if (I.vpos.size() != (I.vbuild.size()) || (nwalls > 0 && I.vpos.size() < 3))
    bad("restore: wall vertex data in '" + group + "' does not match the walls of this system");
  for (std::size_t i = 0; i < n; ++i)
    if (st.material[i] < 0 || static_cast<std::size_t>(st.material[i]) >= I.nmat)
      bad("restore: particle material index out of range in '" + group + "'");
  if (st.shape_id.size() != n || st.scale.size() != n || st.ix.size() != n || st.iy.size() != n ||
      st.iz.size() != n)
    bad("restore: polyhedron arrays in '" + group + "' of " + f.path().string() +
        " do not match the particle count");
  for (std::size_t i = 0; i < n; ++i)
    if (st.shape_id[i] >= static_cast<std::int32_t>(I.shapes.size()) ||
        (st.shape_id[i] >= 0) != (st.shape[i] == static_cast<std::uint8_t>(ParticleShape::polyhedron)))
      bad("restore: particle " + std::to_string(i) + " in '" + group + "' of " +
          f.path().string() + " refers to a shape the state does not hold");
  // the orientation update keeps unit quaternions unit (physics/integrator.hpp), it does not
  // normalise arbitrary ones
  if (st.qw.size() == n && st.qx.size() == n && st.qy.size() == n && st.qz.size() == n)
    for (std::size_t i = 0; i < n; ++i) {
      const double q2 =
          st.qw[i] * st.qw[i] + st.qx[i] * st.qx[i] + st.qy[i] * st.qy[i] + st.qz[i] * st.qz[i];
      if (!(std::abs(q2 - 1.0) < 1e-6))
        bad("restore: orientation of particle " + std::to_string(i) + " in '" + group + "' of " +
            f.path().string() + " is not a unit quaternion (|q|^2 = " + std::to_string(q2) +
            ", accepted 1 +- 1e-6)");
    }
  I.wf.assign(3 * kMaxWallContacts * n, 0.0), I.wp.assign(3 * kMaxWallContacts * n, 0.0),
      I.wb.assign(3 * kMaxWallContacts * n, 0.0), I.wtri.assign(kMaxWallContacts * n, 0);
  I.refresh_particle_derived();
  // The neighbour list is rebuilt from the restored positions; the restored rows carry the
  // springs. Forces of the pairs do not depend on which non-touching pairs the list holds,
  // so the continuation is bitwise identical to an uninterrupted run.
  if (I.row.empty()) I.row.assign(n + 1, 0);  // saved before the first step: no pairs yet
  if (!I.rolling) {
    I.rhist.clear(), I.wroll.clear();
  } else {
    if (I.rhist.empty()) I.rhist.assign(3 * I.nbr.size(), 0.0);
    if (I.wroll.empty()) I.wroll.assign(3 * kMaxWallContacts * n, 0.0);
    if (I.rhist.size() != 3 * I.nbr.size() || I.wroll.size() != 3 * kMaxWallContacts * n)
      bad("restore: rolling history sizes in '" + group + "' of " + f.path().string() +
          " do not match the pair list and particles");
  }
  if (I.wcount.size() != n || I.wkey.size() != kMaxWallContacts * n ||
      I.wshear.size() != 3 * kMaxWallContacts * n || I.row.size() != n + 1)
    bad("restore: inconsistent array sizes in '" + group + "' of " + f.path().string());
  I.need_rebuild = true;
}

void DemSystem::reset_clock() {
  auto& I = *impl_;
  I.t = 0.0;
  I.steps = 0;
  I.update_walls(I.t, I.flex_tau);
}

}  // namespace demfem::dem
