"""A minimal demfem DEM backend in Python: a few spheres falling on the coupled surface.

What it does: the spheres of [dem.external] (centres, radius, mass) fall under gravity onto
the interface mesh the structure published (fem_server's beam, or any FEM backend). Each
sphere touches at most the nearest triangle (its closest point, Ericson's region test): a
linear spring-dashpot in the normal direction, F = (k delta - c v_n) n with c = 2 zeta
sqrt(k m), no friction. The force on the structure, -F, goes to the triangle's three nodes
with the barycentric weights of the contact point. The mesh moves within a coupling step as
the structure's kinematics say (x + v tau + a tau^2 / 2, flag STEP_SET_KINEMATICS), the
spheres by the semi-implicit Euler rule with cmd.substeps steps of cmd.dt / cmd.substeps.
numpy only; about 150 lines.

How to run it: `./demfem run examples/python_dem_spheres/beam_spheres_ci.toml`, whose [dem]
has backend = "external" and command = ["{python}", "spheres.py"] (docs/backends.md, "The DEM
side"). Its keys are [dem.external]'s: centres (m, a list of [x, y, z]), radius (m), mass
(kg per sphere), stiffness (N/m), damping_ratio (-), gravity (m/s^2, [gx, gy, gz]). Test:
tests/protocol/test_python_dem.py (the settled weight on the beam; a killed run's recovery).
"""
import sys

import numpy as np

import demfem


def closest_points(p, a, b, c):
    """Closest point of each triangle (a, b, c: (m, 3)) to the point p (3,): barycentric
    weights (m, 3), Ericson, Real-Time Collision Detection, 5.1.5."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ab = d1 / (d1 - d3)
        w_ac = d2 / (d2 - d6)
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        s = va + vb + vc
        v_in, w_in = vb / s, vc / s
    one, zero = np.ones_like(d1), np.zeros_like(d1)
    regions = [  # Ericson's order: vertex A, B, edge AB, vertex C, edges AC, BC, inside
        ((d1 <= 0) & (d2 <= 0), (one, zero, zero)),
        ((d3 >= 0) & (d4 <= d3), (zero, one, zero)),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), (1 - v_ab, v_ab, zero)),
        ((d6 >= 0) & (d5 <= d6), (zero, zero, one)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), (1 - w_ac, zero, w_ac)),
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), (zero, 1 - w_bc, w_bc)),
    ]
    conds = [r[0] for r in regions]
    return np.stack([np.select(conds, [r[1][k] for r in regions], default)
                     for k, default in enumerate((1 - v_in - w_in, v_in, w_in))], axis=1)


class Spheres(demfem.SolverBackend):
    def __init__(self, p):
        super().__init__()
        self.x = np.array(p["centres"], dtype=float).reshape(-1, 3)
        self.v = np.zeros_like(self.x)
        self.r, self.m, self.k = float(p["radius"]), float(p["mass"]), float(p["stiffness"])
        if not (self.r > 0 and self.m > 0 and self.k > 0):
            raise ValueError("radius, mass and stiffness must be > 0")
        self.c = 2.0 * float(p.get("damping_ratio", 0.0)) * np.sqrt(self.k * self.m)
        self.g = np.array(p.get("gravity", [0.0, 0.0, -9.81]), dtype=float)
        self.tri = None

    def name(self):
        return f"spheres (python, {len(self.x)} spheres of {self.r:g} m, k = {self.k:g} N/m)"

    def published_mesh(self):
        return None  # the DEM side publishes none: it receives the structure's

    def on_mesh(self, mesh):
        self.tri = np.asarray(mesh.triangles, dtype=np.int64)
        self.mesh = np.array(mesh.positions)  # node positions: the reference until kinematics
        self.mesh_v = np.zeros_like(self.mesh)
        self.mesh_a = np.zeros_like(self.mesh)

    def contact(self, i, nodes, node_v, f_nodes):
        """Force of the mesh on sphere i; its reaction goes to f_nodes. Returns (F, overlap)."""
        a, b, c = nodes[self.tri[:, 0]], nodes[self.tri[:, 1]], nodes[self.tri[:, 2]]
        w = closest_points(self.x[i], a, b, c)
        q = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
        dist = np.linalg.norm(self.x[i] - q, axis=1)
        t = int(np.argmin(dist))  # the nearest triangle (the first of equals)
        delta = self.r - dist[t]
        if delta <= 0.0 or dist[t] == 0.0:
            return np.zeros(3), 0.0
        n = (self.x[i] - q[t]) / dist[t]
        v_surface = w[t] @ node_v[self.tri[t]]
        f = (self.k * delta - self.c * float((self.v[i] - v_surface) @ n)) * n
        f_nodes[self.tri[t]] -= w[t][:, None] * f[None, :]
        return f, delta

    def step(self, cmd, buffers):
        if cmd.flags & demfem.STEP_SET_KINEMATICS:
            self.mesh = buffers.positions(cmd.buffer).copy()
            self.mesh_v = buffers.velocities(cmd.buffer).copy()
            self.mesh_a = buffers.accelerations(cmd.buffer).copy()
        n, h = cmd.substeps, cmd.dt / cmd.substeps
        average = cmd.force_mode == demfem.ForceMode.average
        total = np.zeros_like(self.mesh)
        overlap = 0.0
        for s in range(n):
            tau = (s + 1) * h  # the mesh where the substep ends
            nodes = self.mesh + self.mesh_v * tau + 0.5 * self.mesh_a * tau * tau
            node_v = self.mesh_v + self.mesh_a * tau
            f_nodes = np.zeros_like(self.mesh)
            overlap = 0.0
            for i in range(len(self.x)):
                f, delta = self.contact(i, nodes, node_v, f_nodes)
                overlap = max(overlap, delta)
                self.v[i] += h * (f / self.m + self.g)
                self.x[i] += h * self.v[i]
            total = total + f_nodes if average else f_nodes
        buffers.forces(cmd.buffer)[:] = total / n if average else total
        buffers.dem_positions(cmd.buffer)[:] = (self.mesh + self.mesh_v * cmd.dt +
                                                0.5 * self.mesh_a * cmd.dt * cmd.dt)
        kinetic = 0.5 * self.m * float((self.v * self.v).sum())
        return [overlap, kinetic, overlap, float(self.x[:, 2].min())]

    def write_checkpoint(self, path, step):
        state = {"x": self.x, "v": self.v, "mesh": self.mesh, "mesh_v": self.mesh_v,
                 "mesh_a": self.mesh_a, "step": np.array(step)}
        demfem.write_atomically(path, lambda f: np.savez(f, **state))

    def restore_checkpoint(self, path, step):
        with np.load(path) as s:
            if int(s["step"]) != step:
                raise ValueError(f"{path} holds step {int(s['step'])}, not {step}")
            if s["x"].shape != self.x.shape or s["mesh"].shape != self.mesh.shape:
                raise ValueError(f"{path} holds {len(s['x'])} spheres on {len(s['mesh'])} nodes, "
                                 f"this run {len(self.x)} on {len(self.mesh)}")
            self.x, self.v = s["x"].copy(), s["v"].copy()
            self.mesh, self.mesh_v, self.mesh_a = (s["mesh"].copy(), s["mesh_v"].copy(),
                                                   s["mesh_a"].copy())


def main():
    args = demfem.parse_args()
    try:
        backend = Spheres(demfem.load_scene(args.scene, args.set)["dem"]["external"])
    except (KeyError, ValueError, TypeError) as e:  # bad input: exit 2, as demfem's solvers
        print(f"spheres.py: {args.scene}: [dem.external]: {e!r}", file=sys.stderr)
        return demfem.EXIT_BAD_INPUT
    return demfem.run(backend, args, demfem.Role.dem)


if __name__ == "__main__":
    sys.exit(main())
