// spring_bed: an outside FEM backend for demfem, in C++, on the installed protocol package.
//
// The structure is a Winkler foundation: a rectangular surface (size_x x size_y m at height z,
// cells_x x cells_y squares, two triangles each) whose nodes each rest on their own vertical
// spring and dashpot and carry their share of the surface's mass (the lumped mass of a
// bilinear plate): m_i z_i'' + c_i z_i' + k_i z_i = f_i, with k_i, c_i, m_i the bed's
// stiffness (N/m^3), damping (N s/m^3) and areal mass (kg/m^2) times the node's area. Static
// steps solve k_i z_i = f_i, dynamic ones use the trapezoidal rule. It writes its own series,
// <output-dir>/spring_bed.csv (time, total spring force, largest |z|), checkpoints its state
// and restores it, and polls the cancel flag.
//
//   spring_bed --size X Y --cells NX NY --z Z --stiffness K --mass M [--damping C]
//              --scene FILE --segment NAME [--set K=V]... --output-dir DIR [--resume]
//
// demfem passes the second line; the first comes from fem.command.
#include <demfem/protocol/protocol.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

namespace proto = demfem::protocol;
namespace fs = std::filesystem;

namespace {

struct Options {
  double size[2] = {1.0, 1.0}, z = 0.0, stiffness = 0.0, mass = 0.0, damping = 0.0;
  int cells[2] = {1, 1};
  std::string segment, output_dir;
  bool resume = false;
};

Options parse(int argc, char** argv) {
  Options o;
  auto need = [&](int& i, int n) {
    if (i + n >= argc) throw std::invalid_argument(std::string(argv[i]) + " needs a value");
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--size") {
      need(i, 2);
      o.size[0] = std::stod(argv[++i]);
      o.size[1] = std::stod(argv[++i]);
    } else if (a == "--cells") {
      need(i, 2);
      o.cells[0] = std::stoi(argv[++i]);
      o.cells[1] = std::stoi(argv[++i]);
    } else if (a == "--z" || a == "--stiffness" || a == "--mass" || a == "--damping") {
      need(i, 1);
      double& v = a == "--z"           ? o.z
                  : a == "--stiffness" ? o.stiffness
                  : a == "--mass"      ? o.mass
                                       : o.damping;
      v = std::stod(argv[++i]);
    } else if (a == "--segment" || a == "--output-dir") {
      need(i, 1);
      (a == "--segment" ? o.segment : o.output_dir) = argv[++i];
    } else if (a == "--scene" || a == "--set") {
      need(i, 1);
      ++i;  // the scene is not needed: the model is on the command line
    } else if (a == "--resume") {
      o.resume = true;
    } else if (a != "--quiet") {
      throw std::invalid_argument("unknown argument " + a);
    }
  }
  if (o.segment.empty()) throw std::invalid_argument("--segment is required (demfem passes it)");
  if (!(o.size[0] > 0 && o.size[1] > 0 && o.cells[0] > 0 && o.cells[1] > 0 && o.stiffness > 0 &&
        o.mass > 0 && o.damping >= 0))
    throw std::invalid_argument("--size, --cells, --stiffness, --mass must be > 0, --damping >= 0");
  return o;
}

class SpringBed : public proto::SolverBackend {
 public:
  explicit SpringBed(const Options& o) : o_(o) {
    const int nx = o.cells[0], ny = o.cells[1];
    const double hx = o.size[0] / nx, hy = o.size[1] / ny;
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i) {
        mesh_.reference_positions.insert(mesh_.reference_positions.end(), {i * hx, j * hy, o.z});
        // The node's share of the area: a quarter of each adjacent cell.
        const double w = (i == 0 || i == nx ? 0.5 : 1.0) * (j == 0 || j == ny ? 0.5 : 1.0);
        area_.push_back(w * hx * hy);
      }
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const int a = j * (nx + 1) + i, b = a + 1, c = a + nx + 2, d = a + nx + 1;
        mesh_.triangles.insert(mesh_.triangles.end(), {a, b, c, a, c, d});
      }
    const std::size_t n = area_.size();
    z_.assign(n, 0.0);
    v_.assign(n, 0.0);
    a_.assign(n, 0.0);
    if (!o.output_dir.empty()) {
      fs::create_directories(o.output_dir);
      const fs::path csv = fs::path(o.output_dir) / "spring_bed.csv";
      series_.open(csv, o.resume ? std::ios::app : std::ios::trunc);
      if (!o.resume) series_ << "time,spring_force,max_z\n";
    }
  }

  std::string name() const override { return "spring-bed (C++ example, Winkler foundation)"; }
  std::optional<demfem::InterfaceMesh> published_mesh() override { return mesh_; }
  void on_mesh(const demfem::InterfaceMesh&) override {}
  void set_cancel_flag(const std::atomic<bool>* flag) override { cancel_ = flag; }

  proto::StepResult step(const proto::StepCommand& cmd, proto::InterfaceBuffers& b) override {
    const auto f = b.forces(cmd.buffer);  // the particles' forces, in place
    auto x = b.positions(cmd.buffer), v = b.velocities(cmd.buffer),
         acc = b.accelerations(cmd.buffer);
    const double dt = cmd.dt;
    double spring = 0.0, zmax = 0.0;
    for (std::size_t i = 0; i < area_.size(); ++i) {
      if (cancel_ && cancel_->load()) throw std::runtime_error("cancelled");
      const double k = o_.stiffness * area_[i], m = o_.mass * area_[i], c = o_.damping * area_[i];
      const double fi = f[3 * i + 2];
      if (cmd.flags & proto::kStepStatic) {
        z_[i] = fi / k;
        v_[i] = a_[i] = 0.0;
      } else {
        if (!started_) a_[i] = (fi - c * v_[i] - k * z_[i]) / m;
        const double zt = z_[i] + dt * v_[i] + dt * dt / 4 * a_[i], vt = v_[i] + dt / 2 * a_[i];
        const double a1 = (fi - c * vt - k * zt) / (m + c * dt / 2 + k * dt * dt / 4);
        z_[i] = zt + dt * dt / 4 * a1;
        v_[i] = vt + dt / 2 * a1;
        a_[i] = a1;
      }
      for (int d = 0; d < 3; ++d) {
        x[3 * i + d] = mesh_.reference_positions[3 * i + d] + (d == 2 ? z_[i] : 0.0);
        v[3 * i + d] = d == 2 ? v_[i] : 0.0;
        acc[3 * i + d] = d == 2 ? a_[i] : 0.0;
      }
      spring += k * z_[i];
      zmax = std::max(zmax, std::abs(z_[i]));
    }
    if (!(cmd.flags & proto::kStepStatic)) started_ = true;
    if (series_.is_open()) {
      char line[128];
      std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g\n",
                    cmd.time + (cmd.flags & proto::kStepStatic ? 0.0 : dt), spring, zmax);
      series_ << line << std::flush;
    }
    proto::StepResult r;
    r.values[0] = zmax;
    r.values[1] = spring;
    return r;
  }

  void write_checkpoint(const fs::path& file, std::int64_t step) override {
    const fs::path part = file.string() + ".part";
    {
      std::ofstream out(part, std::ios::binary);
      const std::int64_t head[3] = {step, static_cast<std::int64_t>(z_.size()), started_};
      out.write(reinterpret_cast<const char*>(head), sizeof head);
      for (const auto* s : {&z_, &v_, &a_})
        out.write(reinterpret_cast<const char*>(s->data()),
                  static_cast<std::streamsize>(s->size() * sizeof(double)));
      if (!out) throw std::runtime_error("cannot write " + part.string());
    }
    fs::rename(part, file);  // whole or absent
  }

  void restore_checkpoint(const fs::path& file, std::int64_t step) override {
    std::ifstream in(file, std::ios::binary);
    std::int64_t head[3] = {};
    in.read(reinterpret_cast<char*>(head), sizeof head);
    if (!in || head[0] != step || head[1] != static_cast<std::int64_t>(z_.size()))
      throw std::runtime_error(file.string() + ": not a spring_bed state of step " +
                               std::to_string(step) + " with " + std::to_string(z_.size()) +
                               " nodes");
    for (auto* s : {&z_, &v_, &a_})
      in.read(reinterpret_cast<char*>(s->data()),
              static_cast<std::streamsize>(s->size() * sizeof(double)));
    if (!in) throw std::runtime_error(file.string() + ": truncated");
    started_ = head[2] != 0;
  }

 private:
  Options o_;
  demfem::InterfaceMesh mesh_;
  std::vector<double> area_, z_, v_, a_;
  bool started_ = false;
  std::ofstream series_;
  const std::atomic<bool>* cancel_ = nullptr;
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parse(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "spring_bed: " << e.what() << "\n";
    return 2;  // bad input, as demfem's own solvers
  }
  SpringBed bed(o);
  proto::ServeOptions options;
  options.segment = o.segment;
  options.role = proto::Role::fem;
  options.remove_orphaned_segments = true;
  return proto::serve(bed, options);
}
