"""A Python FEM backend that misbehaves on purpose (tests/protocol/test_python_sdk.py).

The spring plate of examples/python_spring_plate, with one fault chosen by --fault:
  exit-before-attach   exits with status 3 before it attaches to the segment
  raise-in-mesh        raises in published_mesh() (an error in its handshake)
  die-in-mesh          dies (os._exit(7)) in published_mesh(), after attaching
  other-size-on-resume publishes a plate of another size when started with --resume
                       (a restarted or resumed process that is not the one that was running)
"""
import argparse
import os
import sys

sys.path.insert(0, os.environ["DEMFEM_EXAMPLES"])  # examples/python_spring_plate
import demfem  # noqa: E402
from spring_plate import SpringPlate  # noqa: E402


class Faulty(SpringPlate):
    def __init__(self, params, fault):
        super().__init__(params)
        self.fault = fault

    def published_mesh(self):
        if self.fault == "raise-in-mesh":
            raise ValueError("the mesh file is broken (a test fault)")
        if self.fault == "die-in-mesh":
            os._exit(7)
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
    return demfem.run(Faulty(params, args.fault), args)


if __name__ == "__main__":
    sys.exit(main())
