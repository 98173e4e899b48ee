"""A minimal demfem FEM backend in Python: a rigid plate on a vertical spring and dashpot.

The plate is the coupled surface: size_x x size_y m at height z, split into cells_x x cells_y
squares (two triangles each). It moves as one body along z:  m z'' + c z' + k z = F_z, with
F_z the sum of the particle forces on its nodes. Static steps solve k z = F_z; dynamic steps
use the trapezoidal rule (Newmark, beta = 1/4, gamma = 1/2). Its parameters are the scene's
[fem.external] keys (docs/backends.md); run it with fem.backend = "external",
fem.command = ["{python}", "spring_plate.py"].
"""
import sys

import numpy as np

import demfem


class SpringPlate(demfem.SolverBackend):
    def __init__(self, p):
        super().__init__()
        self.m, self.c, self.k = p["mass"], p.get("damping", 0.0), p["stiffness"]
        nx, ny = p["cells"]
        x, y = np.meshgrid(np.linspace(0, p["size"][0], nx + 1), np.linspace(0, p["size"][1], ny + 1))
        self.nodes = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, p["z"])])
        tri = []
        for j in range(ny):
            for i in range(nx):
                a = j * (nx + 1) + i
                tri += [[a, a + 1, a + nx + 2], [a, a + nx + 2, a + nx + 1]]
        self.triangles = np.array(tri, dtype=np.int32)
        self.z = self.v = self.a = 0.0  # displacement, velocity, acceleration of the plate
        self.started = False

    def name(self):
        return f"spring-plate (python, k = {self.k:g} N/m, m = {self.m:g} kg)"

    def published_mesh(self):
        return demfem.InterfaceMesh(self.nodes, self.triangles)

    def on_mesh(self, mesh):
        pass

    def step(self, cmd, buffers):
        f = buffers.forces(cmd.buffer)[:, 2].sum()  # N, a view of the shared memory
        if cmd.static:
            self.z, self.v, self.a = f / self.k, 0.0, 0.0
        else:
            dt = cmd.dt
            if not self.started:  # the acceleration of the initial state
                self.a = (f - self.c * self.v - self.k * self.z) / self.m
                self.started = True
            # trapezoidal rule: m a1 + c v1 + k z1 = f with z1, v1 linear in a1
            zt = self.z + dt * self.v + dt * dt / 4 * self.a
            vt = self.v + dt / 2 * self.a
            a1 = (f - self.c * vt - self.k * zt) / (self.m + self.c * dt / 2 + self.k * dt * dt / 4)
            self.z, self.v, self.a = zt + dt * dt / 4 * a1, vt + dt / 2 * a1, a1
        x = buffers.positions(cmd.buffer)  # written in place
        x[:] = self.nodes
        x[:, 2] += self.z
        buffers.velocities(cmd.buffer)[:] = [0.0, 0.0, self.v]
        buffers.accelerations(cmd.buffer)[:] = [0.0, 0.0, self.a]
        return [abs(self.z), 0.5 * self.m * self.v ** 2, 0.5 * self.k * self.z ** 2, cmd.time + cmd.dt]

    def write_checkpoint(self, path, step):
        state = np.array([self.z, self.v, self.a, float(self.started), float(step)])
        demfem.write_atomically(path, lambda f: np.save(f, state))

    def restore_checkpoint(self, path, step):
        with open(path, "rb") as f:
            z, v, a, started, saved = np.load(f)
        if int(saved) != step:
            raise ValueError(f"{path} holds step {int(saved)}, not {step}")
        self.z, self.v, self.a, self.started = z, v, a, bool(started)


def main():
    args = demfem.parse_args()
    try:
        params = demfem.load_scene(args.scene, args.set)["fem"]["external"]
        backend = SpringPlate(params)
    except (KeyError, ValueError, TypeError) as e:  # bad input: exit 2, as demfem's solvers
        print(f"spring_plate.py: {args.scene}: [fem.external]: {e!r}", file=sys.stderr)
        return demfem.EXIT_BAD_INPUT
    return demfem.run(backend, args)


if __name__ == "__main__":
    sys.exit(main())
