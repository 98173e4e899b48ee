import sys

from sweep.cli import main

sys.exit(main(sys.argv[1:]))
