"""Unit-testing a backend without a coupled run: BackendHarness steps a SolverBackend in this
process against interface buffers of its own memory, as demfem's coupler would through the
shared-memory segment.

    from demfem.testing import BackendHarness

    with BackendHarness(SpringPlate(params)) as h:           # a FEM backend: its mesh
        h.step(1e-3, static=True, forces=f)                  # (n, 3) N on the nodes
        z = h.positions[:, 2] - h.mesh.positions[:, 2]       # what the backend wrote, m
        saved = h.checkpoint()                               # write_checkpoint(path, step)
        h.step(1e-3)
        h.restore(saved)                                     # restore_checkpoint(path, step)

    with BackendHarness(Spheres(params), role=Role.dem, mesh=beam_mesh) as h:  # a DEM backend
        h.step(1e-4, substeps=10, kinematics=(x, v, a))      # the structure's, at the start
        f = h.forces                                         # what the backend wrote, N

The backend's methods are called through demfem's C++ interface exactly as serve() calls
them, so what a coupled run would refuse (a wrong return type, more than 8 diagnostics,
complex numbers cast to real) raises here (RuntimeError, or ValueError for complex values)
with the text the run would report.
Checkpoints go to a temporary folder the harness removes when its `with` block ends (or
close() is called), unless a `checkpoint_dir` of the caller's is given.
"""

import collections
import os
import shutil
import tempfile

import numpy as np

from ._protocol import (STEP_SET_KINEMATICS, STEP_STATIC, ForceMode, InterfaceMesh,
                        LocalInterfaceBuffers, Role, StepCommand, attach_cancel_flag,
                        call_name, call_on_mesh, call_published_mesh, call_restore_checkpoint,
                        call_step, call_write_checkpoint)

__all__ = ["BackendHarness", "Checkpoint", "LocalInterfaceBuffers"]

Checkpoint = collections.namedtuple("Checkpoint", "path step time")
Checkpoint.__doc__ = """A checkpoint a BackendHarness wrote: the file, the coupling step it
was written after (the number write_checkpoint() received) and the simulated time, s."""


class BackendHarness:
    """Steps `backend` (a demfem.SolverBackend) in-process as demfem's coupler would.

    role: Role.fem (the backend publishes the interface mesh: published_mesh() is called
    and must return one) or Role.dem (the backend receives `mesh`, an InterfaceMesh, through
    on_mesh(); published_mesh() is called first, as serve() does, and must return None).
    checkpoint_dir: where checkpoint() writes (default: a temporary folder, removed on
    close()). The harness is a context manager; close() detaches the cancel flag and removes
    the temporary folder.
    """

    def __init__(self, backend, role=Role.fem, mesh=None, checkpoint_dir=None):
        self.backend, self.role = backend, role
        self.name = call_name(backend)
        published = call_published_mesh(backend)
        if role == Role.fem:
            if published is None:
                raise ValueError(f"{self.name}: a FEM backend must publish its interface "
                                 "mesh (published_mesh() returned None)")
            if mesh is not None:
                raise ValueError("mesh: a FEM backend publishes its own; pass none")
            self.mesh = published
        else:
            if not isinstance(mesh, InterfaceMesh):
                raise ValueError("mesh: a DEM backend needs the structure's InterfaceMesh")
            self.mesh = mesh
            call_on_mesh(backend, mesh)
        self.buffers = LocalInterfaceBuffers(self.mesh)
        attach_cancel_flag(backend, self.buffers)
        self.step_index, self.time = 0, 0.0
        self._own_dir = checkpoint_dir is None
        self.checkpoint_dir = (tempfile.mkdtemp(prefix="demfem-harness-") if self._own_dir
                               else os.path.abspath(checkpoint_dir))
        self.buffer = 0  # the coupler's sequential schemes use buffer 0 for both solvers
        self._closed = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def close(self):
        """Detaches the cancel flag and removes the temporary checkpoint folder (if the
        harness made it). Called at the end of a `with` block."""
        if self._closed:
            return
        self._closed = True
        attach_cancel_flag(self.backend, None)
        if self._own_dir and os.path.isdir(self.checkpoint_dir):
            shutil.rmtree(self.checkpoint_dir)

    # The arrays of the buffer the next step uses, (n, 3) numpy views (no copy).
    @property
    def positions(self):
        """Node positions, m: the FEM writes them; a DEM reads them (kinematics)."""
        return self.buffers.positions(self.buffer)

    @property
    def velocities(self):
        """Node velocities, m/s (FEM → DEM)."""
        return self.buffers.velocities(self.buffer)

    @property
    def accelerations(self):
        """Node accelerations, m/s^2 (FEM → DEM)."""
        return self.buffers.accelerations(self.buffer)

    @property
    def forces(self):
        """The particles' forces on the nodes, N: a DEM writes them; the FEM reads them."""
        return self.buffers.forces(self.buffer)

    @property
    def dem_positions(self):
        """Where the DEM's copy of the mesh nodes is at the step's end, m (DEM → coupler)."""
        return self.buffers.dem_positions(self.buffer)

    def cancel(self, requested=True):
        """Sets what the backend's `cancelled` property reads (a stop signal in a run)."""
        self.buffers.cancel_requested = requested

    def step(self, dt, *, static=False, substeps=1, forces=None, kinematics=None,
             force_mode=ForceMode.last_substep):
        """One coupling step of dt seconds (a static solve when `static`); returns the 8
        StepDone diagnostics (the values step() returned, then zeros).

        forces: (n, 3) N written into the buffer before the step (the FEM's input; left as
        they are when None). kinematics: (positions, velocities, accelerations), each (n, 3),
        written before the step and announced with STEP_SET_KINEMATICS (the DEM's input;
        no flag when None). substeps and force_mode: the DEM's, as in the scene."""
        if forces is not None:
            self.forces[:] = np.asarray(forces, dtype=float)
        flags = STEP_STATIC if static else 0
        if kinematics is not None:
            x, v, a = kinematics
            self.positions[:], self.velocities[:], self.accelerations[:] = x, v, a
            flags |= STEP_SET_KINEMATICS
        cmd = StepCommand()
        cmd.step, cmd.time, cmd.dt = self.step_index, self.time, float(dt)
        cmd.substeps, cmd.buffer, cmd.force_mode, cmd.flags = int(substeps), self.buffer, force_mode, flags
        values = call_step(self.backend, cmd, self.buffers)
        self.step_index += 1
        self.time += float(dt)
        return values

    def checkpoint(self, path=None):
        """Asks the backend to write a checkpoint after the steps taken so far (as the coupler
        does: write_checkpoint(absolute path, number of steps done)); returns a Checkpoint."""
        path = os.path.abspath(path or os.path.join(self.checkpoint_dir,
                                                    f"checkpoint_{self.step_index}.bin"))
        call_write_checkpoint(self.backend, path, self.step_index)
        return Checkpoint(path, self.step_index, self.time)

    def restore(self, checkpoint):
        """restore_checkpoint(path, step) of a Checkpoint; the harness goes back to its step
        and time."""
        call_restore_checkpoint(self.backend, checkpoint.path, checkpoint.step)
        self.step_index, self.time = checkpoint.step, checkpoint.time
