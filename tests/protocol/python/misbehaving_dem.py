"""A Python DEM backend that misbehaves on purpose (tests/protocol/test_python_dem.py).

The spheres of examples/python_dem_spheres, with one fault chosen by --fault:
  wrong-role      serves the FEM side of the protocol (Role.fem) though started as the DEM
  die-in-step     dies (os._exit(9)) in step() of coupling step 5, in every process
  nan-force       writes NaN into the z force of interface node 12 in step 3
  raise-in-step   raises RuntimeError in step() of coupling step 3
  hang-in-step    sleeps (an hour) in step() of coupling step 5, in the first process only
                  (not in one started with --resume): alive, its heartbeat going
"""
import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.environ["DEMFEM_EXAMPLES"])  # examples/python_dem_spheres
import demfem  # noqa: E402
from spheres import Spheres  # noqa: E402


class Faulty(Spheres):
    def __init__(self, params, fault, resumed):
        super().__init__(params)
        self.fault, self.resumed = fault, resumed

    def step(self, cmd, buffers):
        if self.fault == "die-in-step" and cmd.step == 5:
            os._exit(9)
        if self.fault == "hang-in-step" and cmd.step == 5 and not self.resumed:
            time.sleep(3600.0)
        if self.fault == "raise-in-step" and cmd.step == 3:
            raise RuntimeError("the contact search lost a sphere")
        out = super().step(cmd, buffers)
        if self.fault == "nan-force" and cmd.step == 3:
            buffers.forces(cmd.buffer)[12, 2] = np.nan
        return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--fault", required=True)
    args = demfem.parse_args(parser=parser)
    backend = Faulty(demfem.load_scene(args.scene, args.set)["dem"]["external"], args.fault,
                    args.resume)
    role = demfem.Role.fem if args.fault == "wrong-role" else demfem.Role.dem
    return demfem.run(backend, args, role)


if __name__ == "__main__":
    sys.exit(main())
