"""demfem's Python SDK: attach a structural code (the FEM side) or a particle code (the DEM
side) written in Python to a demfem run.

A backend subclasses SolverBackend and implements

    name()                      -> str, announced in Hello (at most 127 characters kept)
    published_mesh()            -> InterfaceMesh(positions (n, 3), triangles (m, 3))
    on_mesh(mesh)               -> None (called on the DEM side only; a FEM backend passes)
    step(cmd, buffers)          -> None or up to 8 floats (the StepDone diagnostics: max |u|,
                                   kinetic energy, strain energy, ...)
    write_checkpoint(path, step), restore_checkpoint(path, step)

In step(), buffers.forces(cmd.buffer) is an (n, 3) numpy view of the forces the particles
exert on the interface nodes (N), and positions / velocities / accelerations(cmd.buffer)
are (n, 3) views the backend writes (m, m/s, m/s^2), all in shared memory, without a copy.
cmd.static asks for a static solve, otherwise advance by cmd.dt. Long steps may poll
self.cancelled. An exception becomes the error demfem reports, naming the backend. Values are
real: complex numbers returned, or cast to real while a method runs (numpy's ComplexWarning,
e.g. written into an interface view), are errors.

A DEM backend (dem.backend = "external", demfem.run(backend, args, Role.dem)) is the other
way round: on_mesh(mesh) receives the interface mesh (mesh.positions (n, 3), mesh.triangles
(m, 3)); step() reads positions / velocities / accelerations(cmd.buffer) (the structure's
node kinematics at the step's start when cmd.flags has STEP_SET_KINEMATICS), advances
cmd.substeps steps of cmd.dt / cmd.substeps, and writes forces(cmd.buffer) (the particles'
forces on the nodes, N) and dem_positions(cmd.buffer) (where its mesh nodes are at the step's
end, m); it returns [largest overlap with the mesh (m), kinetic energy (J), largest overlap].

The launcher starts the backend as  fem.command (or dem.command) + --scene FILE --segment NAME [--set K=V]...
--output-dir DIR [--resume]  in the scene's folder, every path absolute (the checkpoint paths
of write_checkpoint() and restore_checkpoint() too): parse_args() reads these, load_scene()
reads the scene with the --set overrides, serve() runs the backend. docs/protocol.md.

demfem.testing.BackendHarness steps a backend in-process, without a coupled run, for its unit
tests. Install the package into any Python 3.11+ with `python3 -m pip install protocol/python`
(docs/backends.md).
"""

import argparse
import os
import sys
import tomllib

from ._protocol import (EXIT_BACKEND_ERROR, EXIT_BAD_INPUT, EXIT_COUPLER_DIED, EXIT_OK,
                        EXIT_PROTOCOL_ERROR, EXIT_VERSION_MISMATCH, PROTOCOL_VERSION,
                        STEP_SET_KINEMATICS, STEP_STATIC, ForceMode, InterfaceBuffers,
                        InterfaceMesh, Role, SolverBackend, StepCommand, serve)

__all__ = ["SolverBackend", "InterfaceMesh", "InterfaceBuffers", "StepCommand", "Role",
           "ForceMode", "serve", "parse_args", "load_scene", "write_atomically", "run",
           "PROTOCOL_VERSION", "STEP_STATIC", "STEP_SET_KINEMATICS", "EXIT_OK",
           "EXIT_BACKEND_ERROR", "EXIT_COUPLER_DIED", "EXIT_VERSION_MISMATCH",
           "EXIT_PROTOCOL_ERROR", "EXIT_BAD_INPUT"]

def parse_args(argv=None, parser=None):
    """The arguments demfem passes to a backend: --scene, --segment, --set (repeated),
    --output-dir, --resume, --quiet. Arguments the backend declares on its own `parser` (an
    argparse.ArgumentParser, e.g. from fem.command) are parsed too."""
    p = parser or argparse.ArgumentParser(description="a demfem backend")
    p.add_argument("--scene", required=True, help="the scene file (TOML)")
    p.add_argument("--segment", required=True, help="the coupler's shared-memory segment")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="scene key overrides (demfem run --set), applied by load_scene()")
    p.add_argument("--output-dir", default=None, help="the run's output folder")
    p.add_argument("--resume", action="store_true",
                   help="a restarted or resumed backend: continue the output series")
    p.add_argument("--quiet", action="store_true")
    return p.parse_args(argv)


def _set(table, dotted, value, text):
    parts = dotted.split(".")
    for key in parts[:-1]:
        name, index = key, None
        if key.endswith("]") and "[" in key:
            name, index = key[:-1].split("[")
        if name not in table:
            raise ValueError(f"--set {text}: the scene has no table '{name}'")
        table = table[name]
        if index is not None:
            table = table[int(index)]
    table[parts[-1]] = value


def load_scene(path, sets=()):
    """The scene as nested dicts (tomllib), with the --set KEY=VALUE overrides applied (VALUE
    in TOML, KEY dotted with array indices such as fem.materials[0].density)."""
    with open(path, "rb") as f:
        scene = tomllib.load(f)
    for text in sets:
        key, sep, value = text.partition("=")
        if not sep:
            raise ValueError(f"--set {text}: expected KEY=VALUE")
        _set(scene, key.strip(), tomllib.loads("v = " + value)["v"], text)
    return scene


def write_atomically(path, write):
    """Calls write(file) on `path`.part (binary) and renames it to `path` when complete: a
    checkpoint part is either whole or absent, as demfem's own."""
    part = os.fspath(path) + ".part"
    with open(part, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(part, path)


def run(backend, args, role=Role.fem):
    """serve() with the arguments of parse_args(); returns the exit status for sys.exit().
    `role`: Role.fem for a structure (fem.command), Role.dem for a particle code
    (dem.command); a program started for the other role is refused before it attaches
    (exit 4). The coupler counts as hung after the scene's run.peer_timeout (s, default 10),
    as for demfem's own solvers."""
    timeout = load_scene(args.scene, args.set).get("run", {}).get("peer_timeout", 10.0)
    return serve(backend, args.segment, role, peer_timeout=float(timeout))
