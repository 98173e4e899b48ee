"""A FEM backend built against another demfem: it speaks protocol version 999 (test double for
tests/protocol/test_python_sdk.py, case `version`).

demfem runs it as `fem.command` with `--scene FILE --segment NAME ...`; it replaces itself
(same pid) by protocol_test_peer (DEMFEM_TEST_PEER), whose serve() claims version 999, sees
the segment's version, refuses to attach and exits with 3 (protocol version mismatch).
"""
import os
import sys


def main():
    args = sys.argv[1:]
    segment = args[args.index("--segment") + 1]
    peer = os.environ["DEMFEM_TEST_PEER"]
    os.execv(peer, [peer, "serve", segment, "fem", "--nodes", "63", "--version", "999"])


if __name__ == "__main__":
    main()
