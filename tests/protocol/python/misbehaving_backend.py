"""A Python FEM backend that misbehaves on purpose (tests/protocol/test_python_sdk.py).

The spring plate of examples/python_spring_plate, with one fault chosen by --fault:
  exit-before-attach   exits with status 3 before it attaches to the segment
  raise-in-mesh        raises in published_mesh() (an error in its handshake)
  die-in-mesh          dies (os._exit(7)) in published_mesh(), after attaching
  other-size-on-resume publishes a plate of another size when started with --resume
                       (a restarted or resumed process that is not the one that was running)
  hang-in-step         sleeps (an hour) in step() of coupling step 15, in the first process
                       only (not in one started with --resume): alive, heartbeat going
  spin-in-restore      as hang-in-step; every restarted process then spins (a busy loop
                       holding the GIL) in restore_checkpoint()
  spin-in-restore-once as spin-in-restore, but only the first restarted process spins (it
                       leaves a marker file in --output-dir)
  hang-in-mesh-on-resume as hang-in-step; every restarted process then sleeps (an hour) in
                       published_mesh(), before its Hello
  nan-mesh             publishes an interface mesh whose node 4 has x = NaN
  nan-position         writes NaN into the z position of interface node 3 in step 5
  inf-velocity         writes +inf into the z velocity of interface node 7 in step 5
  complex-return       step() returns complex diagnostics in step 5
  complex-write        step() writes complex velocities into the interface array in step 5
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.environ["DEMFEM_EXAMPLES"])  # examples/python_spring_plate
import demfem  # noqa: E402
from spring_plate import SpringPlate  # noqa: E402


class Faulty(SpringPlate):
    def __init__(self, params, fault, args):
        super().__init__(params)
        self.fault = fault
        self.resumed = args.resume
        self.marker = os.path.join(args.output_dir, "spun-in-restore")

    def step(self, cmd, buffers):
        hang = ("hang-in-step", "spin-in-restore", "spin-in-restore-once",
                "hang-in-mesh-on-resume")
        if self.fault in hang and cmd.step == 15 and not self.resumed:
            time.sleep(3600.0)
        out = super().step(cmd, buffers)
        if cmd.step != 5:
            return out
        if self.fault == "nan-position":
            buffers.positions(cmd.buffer)[3, 2] = np.nan
        elif self.fault == "inf-velocity":
            buffers.velocities(cmd.buffer)[7, 2] = np.inf
        elif self.fault == "complex-return":
            return [np.sqrt(np.complex128(-out[0] - 1.0))] + out[1:]
        elif self.fault == "complex-write":
            buffers.velocities(cmd.buffer)[:] = np.array([0.0, 0.0, self.v]) * (1.0 + 1.0j)
        return out

    def restore_checkpoint(self, path, step):
        spin = self.fault == "spin-in-restore" or (self.fault == "spin-in-restore-once" and
                                                   not os.path.exists(self.marker))
        if spin:
            open(self.marker, "w").close()
            while True:  # a busy loop: the GIL stays with this thread
                pass
        super().restore_checkpoint(path, step)

    def published_mesh(self):
        if self.fault == "hang-in-mesh-on-resume" and self.resumed:
            time.sleep(3600.0)
        if self.fault == "raise-in-mesh":
            raise ValueError("the mesh file is broken (a test fault)")
        if self.fault == "die-in-mesh":
            os._exit(7)
        if self.fault == "nan-mesh":
            nodes = self.nodes.copy()
            nodes[4, 0] = np.nan
            return demfem.InterfaceMesh(nodes, self.triangles)
        return super().published_mesh()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--fault", required=True)
    args = demfem.parse_args(parser=parser)
    if args.fault == "exit-before-attach":
        print("misbehaving_backend.py: exits before it attaches (a test fault)", file=sys.stderr)
        return 3
    params = demfem.load_scene(args.scene, args.set)["fem"]["external"]
    if args.fault == "other-size-on-resume" and args.resume:
        params["cells"] = [10, 2]
    return demfem.run(Faulty(params, args.fault, args), args)


if __name__ == "__main__":
    sys.exit(main())
