#include "demfem/coupling/coupling_settings.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace demfem::coupling {

using scene::Range;
using scene::SceneError;
using scene::Table;

const char* scheme_name(Scheme scheme) {
  switch (scheme) {
    case Scheme::dem_only:
      return "dem_only";
    case Scheme::fem_only:
      return "fem_only";
    case Scheme::one_way_static:
      return "one_way_static";
    case Scheme::just_in_time:
      return "just_in_time";
    case Scheme::predictive:
      return "predictive";
    case Scheme::concurrent:
      return "concurrent";
    case Scheme::implicit:
      return "implicit";
  }
  return "?";
}

namespace {

// Shortest text that reads back as the same double: what the user wrote, usually.
std::string format(double v) {
  char text[32];
  const auto r = std::to_chars(text, text + sizeof(text), v);
  return std::string(text, r.ptr);
}

// A time the run computed (a loaded state's, a sum of steps) in a message: nine digits,
// "0.02" for 0.019999999999999796.
std::string time_text(double t) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.9g", t);
  return text;
}

// A step count for a message: "1e+18", not "1000000000000000128".
std::string count_text(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3g", v);
  return text;
}

// Single-solver runs have no coupling step of their own; the coupler still advances them in
// slices of about this length so that progress and diagnostics come at a steady rate.
constexpr double kSoloSlice = 1e-3;  // s

// Refuses a run whose step counts exceed the limits of coupling_settings.hpp, naming the keys
// that make them (docs/coupling.md).
void check_step_counts(const CouplingSettings& s, const Table& root) {
  const Table run = root.required_table("run");
  const std::string end = run.where("end_time") + " = " + format(s.run.end_time) + " s";
  const double coupling_steps = s.run.end_time / s.coupling_dt;
  if (s.has_fem && !(coupling_steps <= static_cast<double>(kMaxCouplingSteps))) {
    throw SceneError(end + " and " + root.table("fem")->where("dt") + " = " + format(s.fem_dt) +
                     " s make " + count_text(coupling_steps) + " coupling steps; at most " +
                     count_text(kMaxCouplingSteps) +
                     " are accepted. Lower run.end_time or raise fem.dt (both in seconds)");
  }
  if (s.has_dem) {
    const double dem_steps = s.run.end_time / s.dem_dt;
    if (!(dem_steps <= kMaxDemSteps)) {
      throw SceneError(end + " and " + root.table("dem")->where("dt") + " = " + format(s.dem_dt) +
                       " s make " + count_text(dem_steps) + " DEM steps; at most " +
                       count_text(kMaxDemSteps) +
                       " are accepted. Lower run.end_time or raise dem.dt (both in seconds)");
    }
  }
}

// [dem.load] keep_time continues the DEM's clock at the loaded state's time, and the run's
// clock starts there too (start_clock_at, once the state is read): only a DEM alone, whose
// first coupling step is the state's next, can follow. Refused before anything is prepared.
void check_kept_time(const CouplingSettings& s, const Table& dem) {
  const auto load = dem.table("load");
  if (s.dem_external() || !load || !load->has("keep_time") || !load->boolean("keep_time")) return;
  const std::string where = load->where("keep_time");
  if (s.has_fem) {
    throw SceneError(where +
                     ": the DEM would continue at the loaded state's time while the "
                     "structure of [fem] starts at t = 0 (its loads, its output and the "
                     "coupling steps are timed from there); keep_time = true is accepted "
                     "in a scene of [dem] alone. Use keep_time = false here (the clock "
                     "starts at 0; the state's contact history is kept)");
  }
  if (s.dem_settle_time > 0) {
    throw SceneError(where + ": with " + dem.where("settle_time") + " = " +
                     format(s.dem_settle_time) +
                     " s the DEM's clock runs on before the run's first step, away from the "
                     "run's clock, which starts at the state's time; drop settle_time (the run "
                     "itself continues the state: raise run.end_time) or use keep_time = false");
  }
}

// The implicit scheme's keys of [coupling]; any of them with another scheme, or an IQN-ILS key
// with another acceleration, is refused (it would be silently without effect).
void read_implicit_settings(CouplingSettings& s, const Table& c) {
  if (s.scheme != Scheme::implicit) {
    for (const char* key : kImplicitCouplingKeys) {
      if (c.has(key)) c.fail(key, "is only used by scheme = \"implicit\"");
    }
    return;
  }
  ImplicitSettings& im = s.implicit;
  AccelerationSettings& a = im.acceleration;
  const std::string kind = c.choice("acceleration", "iqn-ils", {"iqn-ils", "aitken", "constant"});
  a.kind = kind == "iqn-ils"  ? AccelerationKind::iqn_ils
           : kind == "aitken" ? AccelerationKind::aitken
                              : AccelerationKind::constant;
  im.max_iterations = c.integer("max_iterations", im.max_iterations, 1, 1000);
  im.displacement_tolerance =
      c.number("displacement_tolerance", im.displacement_tolerance, Range::positive());
  im.force_tolerance = c.number("force_tolerance", im.force_tolerance, Range::positive());
  im.displacement_abs_tolerance =
      c.number("displacement_abs_tolerance", 0.0, Range::non_negative());
  im.force_abs_tolerance = c.number("force_abs_tolerance", 0.0, Range::non_negative());
  im.on_nonconvergence = c.choice("on_nonconvergence", "stop", {"stop", "accept"}) == "stop"
                             ? NonConvergence::stop
                             : NonConvergence::accept;
  a.initial_relaxation =
      c.number("initial_relaxation", a.initial_relaxation, Range::open_closed(0.0, 1.0));
  if (a.kind == AccelerationKind::iqn_ils) {
    a.reuse_steps = c.integer("reuse_steps", a.reuse_steps, 0, 1000);
    a.max_columns = c.integer("max_columns", a.max_columns, 1, 10000);
    a.qr_filter = c.number("qr_filter", a.qr_filter, Range{0.0, 1.0, false, true});
  } else {
    for (const char* key : {"reuse_steps", "max_columns", "qr_filter"}) {
      if (c.has(key)) c.fail(key, "is only used by acceleration = \"iqn-ils\"");
    }
  }
}

}  // namespace

std::int64_t dem_substeps(double fem_dt, double dem_dt, const std::string& fem_where,
                          const std::string& dem_where) {
  const double ratio = fem_dt / dem_dt;
  if (!(ratio <= static_cast<double>(kMaxDemSubsteps))) {
    throw SceneError(fem_where + " = " + format(fem_dt) + " s and " + dem_where + " = " +
                     format(dem_dt) + " s make n_D = " + count_text(ratio) +
                     " DEM substeps per coupling step; at most " + count_text(kMaxDemSubsteps) +
                     " are accepted. Raise dem.dt (is it in seconds?) or lower fem.dt");
  }
  const double n = std::round(ratio);
  if (!(n >= 1.0) || std::abs(ratio - n) > kSubstepTolerance * ratio) {
    throw SceneError(fem_where + " = " + format(fem_dt) + " s is not an integer multiple of " +
                     dem_where + " = " + format(dem_dt) + " s (ratio " + format(ratio) +
                     "); the coupling step dt_C = dt_F must equal n_D * dt_D with an integer "
                     "n_D >= 1 (thesis eq. 3.2, relative tolerance 1e-9)");
  }
  return static_cast<std::int64_t>(n);
}

std::int64_t steps_to_reach(double end_time, double dt) {
  const double r = end_time / dt;
  if (!(r < 9e18)) return INT64_MAX;
  const double n = std::round(r);
  if (std::abs(r - n) <= 1e-9 * std::max(1.0, r)) return std::max<std::int64_t>(1, std::llround(n));
  return static_cast<std::int64_t>(std::ceil(r));
}

void start_clock_at(CouplingSettings& s, double time, const std::string& where) {
  // At least one DEM step to make, as dem_server alone does (DemRun::run_to): a run whose
  // end lies before its start would take one step past it.
  if (!(time + 0.5 * s.dem_dt < s.run.end_time)) {
    throw SceneError(s.run.end_time_where + " = " + format(s.run.end_time) +
                     " s is not after t = " + time_text(time) +
                     " s, where the DEM continues its loaded state (" + where +
                     "); run.end_time is an absolute time, not a duration: give one after " +
                     time_text(time) + " s");
  }
  s.start_time = time;
  s.start_time_where = where;
  s.step_count = steps_to_reach(s.run.end_time - time, s.coupling_dt);
}

std::string start_time_mismatch(const CouplingSettings& s, double checkpoint_start) {
  if (checkpoint_start == s.start_time) return {};
  return "its run's clock started at t = " + time_text(checkpoint_start) +
         " s, this run's at t = " + time_text(s.start_time) + " s" +
         (s.start_time_where.empty() ? std::string(" (no [dem.load] keep_time)")
                                     : " (" + s.start_time_where + ": the loaded state's time)") +
         ", so its steps' times differ; resume with the scene and the loaded state it was taken "
         "with, or start afresh";
}

bool names_external_backend(const std::optional<scene::Table>& solver) {
  return solver && solver->has("backend") && solver->string("backend") == "external";
}

CouplingSettings read_coupling_settings(const scene::Document& doc) {
  CouplingSettings s;
  s.run = scene::read_run_settings(doc);
  s.scene_file = doc.file();
  const Table root = doc.root();
  const auto dem = root.table("dem");
  const auto fem = root.table("fem");
  s.has_dem = dem.has_value();
  s.has_fem = fem.has_value();
  if (!s.has_dem && !s.has_fem) {
    throw SceneError(doc.file().string() + ": the scene has neither a [dem] nor a [fem] section; " +
                     "nothing to run");
  }
  // Read-only peeks: the owners check these keys (and the rest of their sections) themselves.
  if (s.has_dem) s.dem_dt = dem->number("dt", Range::positive());
  if (s.has_dem) s.dem_settle_time = dem->number("settle_time", 0.0, Range::non_negative());
  if (s.has_dem) {
    s.dem_backend = dem->choice("backend", "cpu", {"cpu", "cuda", "external"});
    if (s.dem_backend == "external") {
      s.dem_command = dem->strings("command");
      s.dem_command_where = dem->where("command");
    }
  }
  if (s.has_fem) {
    if (fem->has("analysis")) {
      const std::string analysis = fem->string("analysis");
      s.fem_static = analysis == "static";
      s.fem_modal = analysis == "modal";
    }
    s.fem_backend = fem->choice("backend", "fem", {"fem", "modal", "rigid", "external"});
    if (s.fem_backend == "external") {
      s.fem_command = fem->strings("command");
      s.fem_command_where = fem->where("command");
    }
    if (s.fem_modal && s.has_dem)
      throw SceneError(fem->where("analysis") +
                       ": \"modal\" computes the natural frequencies of the structure alone; a "
                       "scene with [dem] couples it in time: use \"dynamic\" or \"static\" (or "
                       "fem.backend = \"modal\" for a modal-reduced structure)");
    if (!(s.fem_static || s.fem_modal) || s.has_dem)
      s.fem_dt = fem->number("dt", Range::positive());
  }

  const auto coupling = root.table("coupling");
  if (s.has_dem && s.has_fem) {
    if (!coupling) {
      throw SceneError(doc.file().string() +
                       ": a scene with both [dem] and [fem] needs a [coupling] section with "
                       "at least 'scheme' (one_way_static, just_in_time, predictive, concurrent "
                       "or implicit)");
    }
    const std::string scheme = coupling->choice(
        "scheme", {"one_way_static", "just_in_time", "predictive", "concurrent", "implicit"});
    s.scheme = scheme == "one_way_static" ? Scheme::one_way_static
               : scheme == "just_in_time" ? Scheme::just_in_time
               : scheme == "predictive"   ? Scheme::predictive
               : scheme == "concurrent"   ? Scheme::concurrent
                                          : Scheme::implicit;
    s.dem_substeps = dem_substeps(s.fem_dt, s.dem_dt, fem->where("dt"), dem->where("dt"));
    s.coupling_dt = s.fem_dt;
  } else if (s.has_dem) {
    s.scheme = Scheme::dem_only;
    const double slice = std::min(kSoloSlice / s.dem_dt, static_cast<double>(kMaxDemSubsteps));
    s.dem_substeps = std::max<std::int64_t>(1, static_cast<std::int64_t>(slice));
    s.coupling_dt = static_cast<double>(s.dem_substeps) * s.dem_dt;
  } else {
    s.scheme = Scheme::fem_only;
    s.dem_substeps = 1;
    s.coupling_dt = s.fem_static || s.fem_modal ? s.run.end_time : s.fem_dt;
  }
  check_step_counts(s, root);
  s.step_count = steps_to_reach(s.run.end_time, s.coupling_dt);
  if (s.has_dem) check_kept_time(s, *dem);

  if (coupling) {
    if (s.scheme == Scheme::dem_only || s.scheme == Scheme::fem_only) {
      // A single-solver scene may keep its [coupling] section (e.g. a variant of a coupled
      // scene) but only the diagnostics keys mean anything there.
      coupling->skip("scheme");
      coupling->skip("force_averaging");
      coupling->skip("settle");
      coupling->skip("blowup");
      coupling->skip("beam_check");
      for (const char* key : kImplicitCouplingKeys) coupling->skip(key);
    } else {
      s.force_averaging = coupling->boolean("force_averaging", false);
      read_implicit_settings(s, *coupling);
      if (auto settle = coupling->table("settle")) {
        if (s.scheme != Scheme::one_way_static) {
          coupling->fail("settle", "is only used by scheme = \"one_way_static\"");
        }
        s.settle_min_time = settle->number("min_time", 0.0, Range::non_negative());
        s.settle_kinetic_energy = settle->number("kinetic_energy", 0.0, Range::non_negative());
        if (s.settle_min_time > s.run.end_time) {
          settle->fail("min_time", "must not exceed run.end_time = " + format(s.run.end_time) +
                                       " s (the DEM stops at run.end_time)");
        }
        settle->finish();
      }
      if (auto blowup = coupling->table("blowup")) {
        s.max_overlap = blowup->number("max_overlap", s.max_overlap, Range::positive());
        s.max_energy_error =
            blowup->number("max_energy_error", s.max_energy_error, Range::positive());
        blowup->finish();
      }
      if (auto beam = coupling->table("beam_check")) {
        BeamCheck b;
        b.probe = beam->vec3("probe");
        b.load_mass = beam->number("load_mass", Range::positive());
        b.gravity = beam->number("gravity", 9.81, Range::positive());
        b.surface = beam->string("surface");
        b.length = beam->number("length", Range::positive());
        b.width = beam->number("width", Range::positive());
        b.height = beam->number("height", Range::positive());
        b.youngs_modulus = beam->number("youngs_modulus", Range::positive());
        beam->finish();
        s.beam_check = b;
      }
    }
    s.diagnostics_interval = coupling->integer("diagnostics_interval", 1, 1, INT64_MAX);
    coupling->finish();
  }
  if (auto cp = root.table("checkpoint")) {
    CheckpointSettings& c = s.checkpoint;
    c.enabled = true;
    c.every_steps = cp->integer("every_steps", 0, 0, INT64_MAX);
    c.every_sim_time = cp->number("every_sim_time", 0.0, Range::non_negative());
    c.every_wall_time = cp->number("every_wall_time", 0.0, Range::non_negative());
    c.keep = cp->integer("keep", 3, 1, 1000000);
    c.max_retries = cp->integer("max_retries", 3, 0, 1000);
    // At most 10^6 s (11.6 days; 0 = no limit): in milliseconds it must fit the wait's clock.
    c.reply_timeout =
        cp->number("reply_timeout", c.reply_timeout, Range::closed(0.0, kMaxReplyTimeout));
    if (cp->has("directory")) c.directory = cp->string("directory");
    cp->finish();
  }
  return s;
}

}  // namespace demfem::coupling
