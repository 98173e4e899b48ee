// Python bindings of the protocol library's solver side (module demfem._protocol; the package
// demfem re-exports it with a few pure-Python helpers). An outside code written in Python
// subclasses SolverBackend and calls serve(): demfem's coupler then drives it exactly as it
// drives fem_server. The interface arrays are numpy views of the shared-memory segment (no
// copy); serve() runs with the GIL released, so the heartbeat and the watchdog threads of the
// protocol library keep running while Python computes, and every call into Python takes the
// GIL. A Python exception becomes the Error message the coupler reports (type, text and the
// innermost frames of the traceback).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

#include "demfem/protocol/protocol.hpp"

namespace py = pybind11;
namespace proto = demfem::protocol;

namespace {

/// The text of a Python exception, taken while the GIL is held.
std::string python_error_text(const py::error_already_set& e) {
  std::string text = e.what();
  // pybind11 appends the traceback ("\n\nAt:\n  file(line): function ..."): keep it short for
  // the 999-character Error message, innermost frames first as pybind11 lists them.
  if (text.size() > 900) text = text.substr(0, 900) + " ...";
  return text;
}

/// numpy's ComplexWarning (numpy.exceptions from numpy 1.25 on, numpy before).
py::object complex_warning() {
  py::module_ np = py::module_::import("numpy");
  return py::hasattr(np, "exceptions") ? np.attr("exceptions").attr("ComplexWarning")
                                       : np.attr("ComplexWarning");
}

/// Refuses complex numbers where demfem takes real ones (`what` names the value): numpy would
/// drop their imaginary parts (a ComplexWarning at most).
void require_real(py::handle values, const std::string& what) {
  if (values.is_none()) return;
  const py::array a = py::array::ensure(values);  // null when it is no array of numbers
  if (a && a.dtype().kind() == 'c')
    throw std::invalid_argument(what + " holds complex numbers (dtype " +
                                py::str(a.dtype()).cast<std::string>() +
                                "); demfem's values are real: pass .real or abs() of them");
}

/// A (n, 3) float64 numpy view of an interface array, kept alive by `owner`.
py::array_t<double> view(std::span<double> a, py::handle owner) {
  const auto n = static_cast<py::ssize_t>(a.size() / 3);
  return py::array_t<double>({n, py::ssize_t{3}},
                             {py::ssize_t{3 * sizeof(double)}, py::ssize_t{sizeof(double)}},
                             a.data(), owner);
}

class PySolverBackend : public proto::SolverBackend {
 public:
  std::string name() const override {
    return call<std::string>("name", [](py::object r) { return r.cast<std::string>(); });
  }
  std::optional<demfem::InterfaceMesh> published_mesh() override {
    return call<std::optional<demfem::InterfaceMesh>>(
        "published_mesh", [](py::object r) -> std::optional<demfem::InterfaceMesh> {
          if (r.is_none()) return std::nullopt;
          return r.cast<demfem::InterfaceMesh>();
        });
  }
  void on_mesh(const demfem::InterfaceMesh& mesh) override {
    call<int>(
        "on_mesh", [](py::object) { return 0; }, mesh);
  }
  proto::StepResult step(const proto::StepCommand& cmd, proto::InterfaceBuffers& buffers) override {
    return call<proto::StepResult>(
        "step",
        [](py::object r) {
          proto::StepResult out;
          if (r.is_none()) return out;
          require_real(r, "the list step() returned");
          const auto values = r.cast<std::vector<double>>();
          if (values.size() > out.values.size())
            throw std::runtime_error("step() returned " + std::to_string(values.size()) +
                                     " values; at most 8 are reported");
          std::copy(values.begin(), values.end(), out.values.begin());
          return out;
        },
        cmd, py::cast(&buffers, py::return_value_policy::reference));
  }
  void write_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    call<int>(
        "write_checkpoint", [](py::object) { return 0; }, file.string(), step);
  }
  void restore_checkpoint(const std::filesystem::path& file, std::int64_t step) override {
    call<int>(
        "restore_checkpoint", [](py::object) { return 0; }, file.string(), step);
  }
  void set_cancel_flag(const std::atomic<bool>* flag) override { cancel_ = flag; }
  bool cancelled() const { return cancel_ && cancel_->load(std::memory_order_relaxed); }

 private:
  // Calls the Python method with numpy's ComplexWarning raised as an error: a complex value
  // written into an interface array (a real numpy view of the shared memory) would otherwise
  // lose its imaginary part with a warning nobody reads.
  template <class R, class Convert, class... Args>
  R call(const char* method, Convert convert, Args&&... args) const {
    py::gil_scoped_acquire gil;
    try {
      py::function f = py::get_override(static_cast<const proto::SolverBackend*>(this), method);
      if (!f)
        throw std::runtime_error(std::string("the backend does not implement ") + method + "()");
      py::module_ warnings = py::module_::import("warnings");
      py::object strict = warnings.attr("catch_warnings")();
      strict.attr("__enter__")();
      py::object result;
      try {
        warnings.attr("simplefilter")("error", complex_warning());
        result = f(std::forward<Args>(args)...);
      } catch (...) {
        strict.attr("__exit__")(py::none(), py::none(), py::none());
        throw;
      }
      strict.attr("__exit__")(py::none(), py::none(), py::none());
      return convert(result);
    } catch (py::error_already_set& e) {
      // Converted here, with the GIL held: the error object must not outlive it.
      if (e.matches(complex_warning()))
        throw std::runtime_error(
            std::string(method) +
            "() cast complex numbers to real, dropping their imaginary parts (into an "
            "interface array, a float64 view, or elsewhere; an error while demfem calls the "
            "backend): take .real or abs() of them explicitly: " +
            python_error_text(e));
      throw std::runtime_error(python_error_text(e));
    } catch (const py::cast_error& e) {
      throw std::runtime_error(std::string(method) + "() returned the wrong type: " + e.what());
    }
  }
  const std::atomic<bool>* cancel_ = nullptr;
};

/// InterfaceBuffers over memory of its own, for a backend stepped in-process without a coupled
/// run (demfem.testing.BackendHarness): the layout of the bulk segment (reference mesh, then
/// [buffer][positions, velocities, accelerations, forces, dem_positions][3n], as
/// InterfaceBuffers::bind() and the coupler's in-process link lay it out), both buffers'
/// positions and dem_positions at the reference, as the coupler's first mesh exchange leaves
/// them. It also holds the cancel flag a harness raises (SolverBackend.cancelled).
class OwnedInterfaceBuffers : public proto::InterfaceBuffers {
 public:
  explicit OwnedInterfaceBuffers(const demfem::InterfaceMesh& mesh)
      : reference_(mesh.reference_positions),
        triangles_(mesh.triangles),
        arrays_(kBufferCount * 5 * 3 * mesh.node_count(), 0.0) {
    bind(mesh.node_count(), mesh.triangle_count(), reference_.data(), triangles_.data(),
         arrays_.data());
    for (std::uint32_t b = 0; b < kBufferCount; ++b) {
      std::copy(reference_.begin(), reference_.end(), positions(b).begin());
      std::copy(reference_.begin(), reference_.end(), dem_positions(b).begin());
    }
  }
  std::atomic<bool> cancel{false};

 private:
  std::vector<double> reference_;
  std::vector<std::int32_t> triangles_;
  std::vector<double> arrays_;
};

// The backend's methods called through the C++ interface, as serve() calls them: the same
// checks of what they return (types, at most 8 real diagnostics, no complex numbers cast
// to real), the same error text. demfem.testing.BackendHarness steps a backend with them.
void def_backend_calls(py::module_& m) {
  m.def(
      "call_name", [](proto::SolverBackend& b) { return b.name(); }, py::arg("backend"),
      "backend.name() as serve() calls it (for Hello)");
  m.def(
      "call_published_mesh", [](proto::SolverBackend& b) { return b.published_mesh(); },
      py::arg("backend"), "backend.published_mesh() as serve() calls it: an InterfaceMesh or None");
  m.def(
      "call_on_mesh",
      [](proto::SolverBackend& b, const demfem::InterfaceMesh& mesh) { b.on_mesh(mesh); },
      py::arg("backend"), py::arg("mesh"), "backend.on_mesh(mesh) as serve() calls it");
  m.def(
      "call_step",
      [](proto::SolverBackend& b, const proto::StepCommand& cmd, proto::InterfaceBuffers& buffers) {
        return b.step(cmd, buffers).values;
      },
      py::arg("backend"), py::arg("cmd"), py::arg("buffers"),
      "backend.step(cmd, buffers) as serve() calls it; returns the 8 StepDone diagnostics "
      "(zeros after the ones the backend returned)");
  m.def(
      "call_write_checkpoint",
      [](proto::SolverBackend& b, const std::string& path, std::int64_t step) {
        b.write_checkpoint(path, step);
      },
      py::arg("backend"), py::arg("path"), py::arg("step"),
      "backend.write_checkpoint(path, step) as serve() calls it");
  m.def(
      "call_restore_checkpoint",
      [](proto::SolverBackend& b, const std::string& path, std::int64_t step) {
        b.restore_checkpoint(path, step);
      },
      py::arg("backend"), py::arg("path"), py::arg("step"),
      "backend.restore_checkpoint(path, step) as serve() calls it");
  m.def(
      "attach_cancel_flag",
      [](proto::SolverBackend& b, OwnedInterfaceBuffers* buffers) {
        b.set_cancel_flag(buffers != nullptr ? &buffers->cancel : nullptr);
      },
      py::arg("backend"), py::arg("buffers").none(true), py::keep_alive<1, 2>(),
      "backend.cancelled follows buffers.cancel_requested from now on (None: detaches); the "
      "backend keeps the buffers alive");
}

}  // namespace

PYBIND11_MODULE(_protocol, m) {
  m.doc() = "demfem inter-process protocol, solver side (see docs/protocol.md)";
  m.attr("PROTOCOL_VERSION") = proto::kProtocolVersion;
  m.attr("STEP_STATIC") = proto::kStepStatic;
  m.attr("STEP_SET_KINEMATICS") = proto::kStepSetKinematics;
  m.attr("EXIT_OK") = proto::kExitOk;
  m.attr("EXIT_BACKEND_ERROR") = proto::kExitBackendError;
  m.attr("EXIT_COUPLER_DIED") = proto::kExitCouplerDied;
  m.attr("EXIT_VERSION_MISMATCH") = proto::kExitVersionMismatch;
  m.attr("EXIT_PROTOCOL_ERROR") = proto::kExitProtocolError;
  // A backend that refuses its scene exits as demfem's own solvers do (the run's code).
  m.attr("EXIT_BAD_INPUT") = demfem::kExitBadInput;

  py::enum_<proto::Role>(m, "Role", "Which side of the coupling a program serves")
      .value("dem", proto::Role::dem, "the particles (dem.backend, dem.command)")
      .value("fem", proto::Role::fem, "the structure (fem.backend, fem.command)");
  py::enum_<demfem::ForceMode>(m, "ForceMode",
                               "Which forces a DEM writes after a coupling step's substeps")
      .value("last_substep", demfem::ForceMode::last_substep, "those of the last substep")
      .value("average", demfem::ForceMode::average,
             "their average over the substeps (coupling.force_averaging)");

  py::class_<proto::StepCommand>(m, "StepCommand", "What a Step message asks for")
      .def(py::init<>())
      .def_readwrite("step", &proto::StepCommand::step, "coupling step index (0-based)")
      .def_readwrite("time", &proto::StepCommand::time, "simulated time at the step's start, s")
      .def_readwrite("dt", &proto::StepCommand::dt, "coupling step, s")
      .def_readwrite("substeps", &proto::StepCommand::substeps)
      .def_readwrite("buffer", &proto::StepCommand::buffer, "interface buffer, 0 or 1")
      .def_readwrite("force_mode", &proto::StepCommand::force_mode)
      .def_readwrite("flags", &proto::StepCommand::flags)
      .def_property_readonly(
          "static", [](const proto::StepCommand& c) { return (c.flags & proto::kStepStatic) != 0; },
          "a static solve instead of a dynamic step (the one-way static scheme)")
      .def("__repr__", [](const proto::StepCommand& c) {
        return "StepCommand(step=" + std::to_string(c.step) + ", time=" + std::to_string(c.time) +
               ", dt=" + std::to_string(c.dt) + ", buffer=" + std::to_string(c.buffer) +
               ", flags=" + std::to_string(c.flags) + ")";
      });

  py::class_<demfem::InterfaceMesh>(m, "InterfaceMesh",
                                    "The coupled surface: node positions (n, 3) in m and "
                                    "triangles (m, 3) of node indices, normals outward")
      .def(py::init([](py::object positions_in, py::object triangles_in) {
             require_real(positions_in, "InterfaceMesh: positions");
             using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;
             using Ints = py::array_t<std::int32_t, py::array::c_style | py::array::forcecast>;
             const auto positions = positions_in.cast<Doubles>();
             const auto triangles = triangles_in.cast<Ints>();
             if (positions.ndim() != 2 || positions.shape(1) != 3)
               throw std::invalid_argument("InterfaceMesh: positions must be an (n, 3) array");
             if (triangles.ndim() != 2 || triangles.shape(1) != 3)
               throw std::invalid_argument("InterfaceMesh: triangles must be an (m, 3) array");
             demfem::InterfaceMesh mesh;
             mesh.reference_positions.assign(positions.data(), positions.data() + positions.size());
             mesh.triangles.assign(triangles.data(), triangles.data() + triangles.size());
             return mesh;
           }),
           py::arg("positions"), py::arg("triangles"))
      .def_property_readonly("node_count", &demfem::InterfaceMesh::node_count)
      .def_property_readonly("triangle_count", &demfem::InterfaceMesh::triangle_count)
      .def_property_readonly(
          "positions",
          [](const demfem::InterfaceMesh& mm) {
            py::array_t<double> a({static_cast<py::ssize_t>(mm.node_count()), py::ssize_t{3}});
            std::copy(mm.reference_positions.begin(), mm.reference_positions.end(),
                      a.mutable_data());
            return a;
          })
      .def_property_readonly("triangles", [](const demfem::InterfaceMesh& mm) {
        py::array_t<std::int32_t> a(
            {static_cast<py::ssize_t>(mm.triangle_count()), py::ssize_t{3}});
        std::copy(mm.triangles.begin(), mm.triangles.end(), a.mutable_data());
        return a;
      });

  py::class_<proto::InterfaceBuffers>(
      m, "InterfaceBuffers",
      "The interface arrays in shared memory. positions/velocities/accelerations (written by "
      "the FEM), forces (written by the DEM: the forces the particles exert on the structure) "
      "and dem_positions return (n, 3) numpy views without a copy; valid during the call that "
      "received them")
      .def_property_readonly("node_count", &proto::InterfaceBuffers::node_count)
      .def_property_readonly("triangle_count", &proto::InterfaceBuffers::triangle_count)
      .def(
          "positions",
          [](py::object self, std::uint32_t b) {
            return view(self.cast<proto::InterfaceBuffers&>().positions(b), self);
          },
          py::arg("buffer"))
      .def(
          "velocities",
          [](py::object self, std::uint32_t b) {
            return view(self.cast<proto::InterfaceBuffers&>().velocities(b), self);
          },
          py::arg("buffer"))
      .def(
          "accelerations",
          [](py::object self, std::uint32_t b) {
            return view(self.cast<proto::InterfaceBuffers&>().accelerations(b), self);
          },
          py::arg("buffer"))
      .def(
          "forces",
          [](py::object self, std::uint32_t b) {
            return view(self.cast<proto::InterfaceBuffers&>().forces(b), self);
          },
          py::arg("buffer"))
      .def(
          "dem_positions",
          [](py::object self, std::uint32_t b) {
            return view(self.cast<proto::InterfaceBuffers&>().dem_positions(b), self);
          },
          py::arg("buffer"))
      .def("reference_mesh", &proto::InterfaceBuffers::reference_mesh);

  py::class_<OwnedInterfaceBuffers, proto::InterfaceBuffers>(
      m, "LocalInterfaceBuffers",
      "InterfaceBuffers in the process's own memory, for a backend stepped without a coupled "
      "run (demfem.testing.BackendHarness): both buffers' positions and dem_positions start at "
      "the mesh's reference positions, every other array at zero")
      .def(py::init<const demfem::InterfaceMesh&>(), py::arg("mesh"))
      .def_property(
          "cancel_requested", [](const OwnedInterfaceBuffers& b) { return b.cancel.load(); },
          [](OwnedInterfaceBuffers& b, bool v) { b.cancel.store(v); },
          "the flag a backend attached with attach_cancel_flag() sees as its `cancelled`");

  py::class_<proto::SolverBackend, PySolverBackend>(
      m, "SolverBackend",
      "Subclass it and implement name(), published_mesh(), on_mesh(mesh), step(cmd, buffers), "
      "write_checkpoint(path, step) and restore_checkpoint(path, step); then call serve()")
      .def(py::init<>())
      .def_property_readonly(
          "cancelled",
          [](const proto::SolverBackend& b) {
            const auto* p = dynamic_cast<const PySolverBackend*>(&b);
            return p != nullptr && p->cancelled();
          },
          "True when a long step should be abandoned (a stop signal, or the coupler is gone): "
          "poll it and raise to stop");

  def_backend_calls(m);

  m.def(
      "serve",
      [](proto::SolverBackend& backend, const std::string& segment, proto::Role role,
         double peer_timeout, bool handle_signals, bool remove_orphaned_segments) {
        proto::ServeOptions o;
        o.segment = segment;
        o.role = role;
        o.peer_timeout = std::chrono::milliseconds(static_cast<std::int64_t>(peer_timeout * 1000));
        o.handle_signals = handle_signals;
        o.remove_orphaned_segments = remove_orphaned_segments;
        py::gil_scoped_release release;
        return proto::serve(backend, o);
      },
      py::arg("backend"), py::arg("segment"), py::arg("role") = proto::Role::fem,
      py::arg("peer_timeout") = 2.0, py::arg("handle_signals") = true,
      py::arg("remove_orphaned_segments") = true,
      "Attaches to the coupler's segment (--segment), says Hello with the backend's mesh and "
      "serves Step, Checkpoint, Restore until Shutdown. Returns the process exit status: 0 "
      "after Shutdown, 1 the backend raised (its error went to the coupler), 2 the coupler "
      "died, 3 protocol version mismatch, 4 protocol error, 128 + N signal N");
}
