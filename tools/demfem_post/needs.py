"""Optional modules (numpy, pandas, matplotlib): an import that fails names the Debian
package and the interpreter that has it, instead of a bare ModuleNotFoundError."""

import importlib
import sys


class MissingModule(ImportError):
    """A module the post-processing needs is not importable by this interpreter."""


def need(module, debian_package):
    """Imports `module`, or raises MissingModule naming the package and the interpreter."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingModule(
            f"{module} is missing in {sys.executable} (Python {sys.version.split()[0]}): install "
            f"Debian's {debian_package}, or run with /usr/bin/python3 where it is installed"
        ) from None
