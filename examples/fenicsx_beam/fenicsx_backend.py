"""FEniCSx (Debian's python3-dolfinx 0.5) as a demfem FEM backend: linear elasticity of a
box-shaped structure, read from the same [fem] keys as fem_server, coupled through the Python
SDK without any change to demfem: the proof that an outside FEM code attaches.

What it reads from the scene (docs/backends.md, "FEniCSx"): fem.mesh.box (lo, hi, cells;
hexahedra), one [[fem.materials]] entry, [[fem.clamps]] with coordinate selectors ("x <= 0",
"x >= 1.0 and z <= 0", dofs x/y/z), fem.gravity, fem.interface_surface (a coordinate selector,
or the whole exterior), [fem.bossak] and [fem.damping]; and its own [fem.external] keys:
degree (Lagrange order on the hexahedra, default 2) and cells (its own mesh, default the
box's). Pressures and nodal loads are refused (the example has none).

The coupled surface is its exterior surface (or the selected part) triangulated through every
Lagrange node (a Q2 face: 9 nodes, 8 triangles), so that the particles' forces act as nodal
loads, one to one. Static steps solve K u = f; dynamic steps are demfem's Bossak-Newmark step
(the same parameters, Rayleigh damping C = cm M + ck K) with consistent mass. Linear systems:
PETSc, LU (MUMPS), factorised once per matrix.
"""
import logging
import re
import sys

import numpy as np

logging.getLogger().setLevel(logging.WARNING)  # FFCx's JIT compiler logs at INFO

import ufl  # noqa: E402
from dolfinx import fem, mesh  # noqa: E402
import dolfinx.fem.petsc  # noqa: E402,F401
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

import demfem  # noqa: E402


class SceneError(ValueError):
    pass


def selector(text, diag):
    """demfem's coordinate selector ("x <= 0 and y > 0.05", docs/scene_fem.md) as a predicate
    on (3, n) point arrays, with its tolerance 1e-6 x the bounding-box diagonal."""
    tol = 1e-6 * diag
    tests = []
    for clause in text.split(" and "):
        m = re.fullmatch(r"\s*([xyz])\s*(<=|>=|==|<|>)\s*([-+0-9.eE]+)\s*", clause)
        if not m:
            raise SceneError(f"selector '{text}': this example reads 'x|y|z OP number' clauses only")
        c, op, v = "xyz".index(m.group(1)), m.group(2), float(m.group(3))
        tests.append({"<=": lambda p, c=c, v=v: p[c] <= v + tol, ">=": lambda p, c=c, v=v: p[c] >= v - tol,
                      "==": lambda p, c=c, v=v: np.abs(p[c] - v) <= tol,
                      "<": lambda p, c=c, v=v: p[c] < v - tol, ">": lambda p, c=c, v=v: p[c] > v + tol}[op])
    return lambda p: np.logical_and.reduce([t(p) for t in tests])


class Elasticity(demfem.SolverBackend):
    def __init__(self, scene):
        super().__init__()
        f = scene["fem"]
        ext = f.get("external", {})
        box = f.get("mesh", {}).get("box")
        if box is None or box.get("element", "hex8") != "hex8":
            raise SceneError("[fem.mesh.box] with element = \"hex8\" is required")
        for key in ("pressures", "nodal_loads"):
            if f.get(key):
                raise SceneError(f"[[fem.{key}]] is not supported by this example")
        if len(f.get("materials", [])) != 1:
            raise SceneError("exactly one [[fem.materials]] entry is required")
        mat = f["materials"][0]
        e, nu, self.rho = mat["youngs_modulus"], mat["poisson_ratio"], mat["density"]
        lo, hi = np.array(box["lo"], float), np.array(box["hi"], float)
        cells = ext.get("cells", box["cells"])
        self.degree = ext.get("degree", 2)
        self.domain = mesh.create_box(MPI.COMM_SELF, [lo, hi], cells, cell_type=mesh.CellType.hexahedron)
        V = self.V = fem.VectorFunctionSpace(self.domain, ("Lagrange", self.degree))
        diag = float(np.linalg.norm(hi - lo))
        bcs = []
        for c in f.get("clamps", []):
            where = selector(c["nodes"], diag)
            for comp in [("x", "y", "z").index(d) for d in c.get("dofs", ["x", "y", "z"]) if d in "xyz"]:
                dofs = fem.locate_dofs_geometrical((V.sub(comp), V.sub(comp).collapse()[0]), where)[0]
                bcs.append(fem.dirichletbc(PETSc.ScalarType(0), dofs, V.sub(comp)))
        self.bcs = bcs
        lam, mu = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        eps = lambda w: ufl.sym(ufl.grad(w))  # noqa: E731
        sigma = lambda w: lam * ufl.tr(eps(w)) * ufl.Identity(3) + 2 * mu * eps(w)  # noqa: E731
        self.K = dolfinx.fem.petsc.assemble_matrix(fem.form(ufl.inner(sigma(u), eps(v)) * ufl.dx), bcs=bcs)
        self.K.assemble()
        self.M = dolfinx.fem.petsc.assemble_matrix(fem.form(self.rho * ufl.inner(u, v) * ufl.dx), bcs=bcs)
        self.M.assemble()
        g = np.array(f.get("gravity", [0.0, 0.0, 0.0]), float)
        self.body = dolfinx.fem.petsc.assemble_vector(
            fem.form(ufl.inner(fem.Constant(self.domain, PETSc.ScalarType(self.rho * g)), v) * ufl.dx))
        bo = f.get("bossak", {})
        self.alpha = bo.get("alpha", -0.1)
        self.gamma = bo.get("gamma", 0.5 - self.alpha)
        self.beta = bo.get("beta", (1 - self.alpha) ** 2 / 4)
        self.cm = f.get("damping", {}).get("mass_factor", 0.0)
        self.ck = f.get("damping", {}).get("stiffness_factor", 0.0)
        self._interface(f.get("interface_surface", "exterior"), diag)
        n = self.K.getSize()[0]
        self.u, self.v, self.a = (np.zeros(n) for _ in range(3))
        self.started, self.dt, self.solver = False, None, {}
        self.time = 0.0

    def _interface(self, surface, diag):
        """Exterior faces (or those all of whose nodes the selector takes), triangulated through
        their (degree + 1)^2 Lagrange nodes, outward."""
        d, fdim = self.domain, self.domain.topology.dim - 1
        d.topology.create_connectivity(fdim, fdim + 1)
        xyz = self.V.tabulate_dof_coordinates()
        centre = xyz.mean(axis=0)
        take = None if surface in ("exterior", "") else selector(surface, diag)
        nodes, index, triangles = [], {}, []
        p = self.degree
        for facet in mesh.exterior_facet_indices(d.topology):
            blocks = fem.locate_dofs_topological(self.V, fdim, np.array([facet], dtype=np.int32))
            pts = xyz[blocks]
            if take is not None and not take(pts.T).all():
                continue
            normal = int(np.argmin(np.ptp(pts, axis=0)))  # the constant coordinate
            a, b = [k for k in range(3) if k != normal]
            order = np.lexsort((pts[:, a], pts[:, b]))  # (p + 1) x (p + 1) grid, a fastest
            grid = blocks[order].reshape(p + 1, p + 1)
            out = 1.0 if pts[0, normal] > centre[normal] else -1.0
            for blk in grid.ravel():
                if blk not in index:
                    index[blk] = len(nodes)
                    nodes.append(blk)
            for j in range(p):
                for i in range(p):
                    q = [index[grid[j, i]], index[grid[j, i + 1]], index[grid[j + 1, i + 1]], index[grid[j + 1, i]]]
                    for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]]):
                        x0, x1, x2 = (xyz[nodes[k]] for k in t)
                        if np.cross(x1 - x0, x2 - x0)[normal] * out < 0:
                            t = [t[0], t[2], t[1]]
                        triangles.append(t)
        self.iface = np.array(nodes, dtype=np.int64)
        self.iface_xyz = xyz[self.iface].copy()
        self.triangles = np.array(triangles, dtype=np.int32)
        self.rows = (3 * self.iface[:, None] + np.arange(3)[None, :]).ravel()

    def _lu(self, key, matrix):
        if key not in self.solver:
            ksp = PETSc.KSP().create(MPI.COMM_SELF)
            ksp.setOperators(matrix)
            ksp.setType("preonly")
            ksp.getPC().setType("lu")
            ksp.getPC().setFactorSolverType("mumps")
            self.solver[key] = ksp
        return self.solver[key]

    def _solve(self, key, matrix, rhs):
        b = PETSc.Vec().createWithArray(rhs.copy())
        dolfinx.fem.petsc.set_bc(b, self.bcs)  # zero at the clamped DOFs
        x = b.duplicate()
        self._lu(key, matrix).solve(b, x)
        return x.getArray().copy()

    def _mat(self, matrix, x):
        y = matrix.createVecLeft()
        matrix.mult(PETSc.Vec().createWithArray(np.ascontiguousarray(x)), y)
        return y.getArray().copy()

    def name(self):
        return f"fenicsx-elasticity (dolfinx Q{self.degree}, {self.K.getSize()[0]} DOF)"

    def published_mesh(self):
        return demfem.InterfaceMesh(self.iface_xyz, self.triangles)

    def on_mesh(self, mesh_):
        pass

    def step(self, cmd, buffers):
        load = self.body.getArray().copy()
        load[self.rows] += buffers.forces(cmd.buffer).ravel()  # nodal loads, one to one
        if cmd.static:
            self.u = self._solve("K", self.K, load)
            self.v[:] = 0.0
            self.a[:] = 0.0
        else:
            dt, al, be, ga = cmd.dt, self.alpha, self.beta, self.gamma
            if not self.started:
                rhs = load - self.cm * self._mat(self.M, self.v) - self._mat(self.K, self.u + self.ck * self.v)
                self.a = self._solve("M", self.M, rhs)
                self.started = True
            if dt != self.dt:  # (1 - alpha) M + gamma dt C + beta dt^2 K, C = cm M + ck K
                eff = self.M.copy()
                eff.scale((1 - al) + ga * dt * self.cm)
                eff.axpy(be * dt * dt + ga * dt * self.ck, self.K)
                self.eff, self.dt = eff, dt
                self.solver.pop("eff", None)
            ut = self.u + dt * self.v + dt * dt * (0.5 - be) * self.a
            vt = self.v + dt * (1 - ga) * self.a
            rhs = load - self._mat(self.M, al * self.a + self.cm * vt) - self._mat(self.K, ut + self.ck * vt)
            a1 = self._solve("eff", self.eff, rhs)
            self.u, self.v, self.a = ut + be * dt * dt * a1, vt + ga * dt * a1, a1
        x = buffers.positions(cmd.buffer)
        x[:] = self.iface_xyz + self.u[self.rows].reshape(-1, 3)
        buffers.velocities(cmd.buffer)[:] = self.v[self.rows].reshape(-1, 3)
        buffers.accelerations(cmd.buffer)[:] = self.a[self.rows].reshape(-1, 3)
        umax = float(np.max(np.linalg.norm(self.u.reshape(-1, 3), axis=1)))
        ke = 0.5 * float(self.v @ self._mat(self.M, self.v))
        se = 0.5 * float(self.u @ self._mat(self.K, self.u))
        return [umax, ke, se, cmd.time + (0.0 if cmd.static else cmd.dt)]

    def write_checkpoint(self, path, step):
        def write(f):
            np.savez(f, u=self.u, v=self.v, a=self.a, step=step, started=self.started)
        demfem.write_atomically(path, write)

    def restore_checkpoint(self, path, step):
        with np.load(path) as z:
            if int(z["step"]) != step or z["u"].shape != self.u.shape:
                raise ValueError(f"{path}: not this model's state of step {step}")
            self.u, self.v, self.a = z["u"].copy(), z["v"].copy(), z["a"].copy()
            self.started = bool(z["started"])


def main():
    args = demfem.parse_args()
    try:
        backend = Elasticity(demfem.load_scene(args.scene, args.set))
    except (SceneError, KeyError, TypeError) as e:
        print(f"fenicsx_backend.py: {args.scene}: [fem]: {e}", file=sys.stderr)
        return demfem.EXIT_BAD_INPUT
    return demfem.run(backend, args)


if __name__ == "__main__":
    sys.exit(main())
