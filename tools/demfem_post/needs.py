"""Optional modules (numpy, pandas, matplotlib, ParaView's Python): an import that fails
names the module, the interpreter that lacked it, the Debian package and the interpreter to
run with, instead of a bare ModuleNotFoundError."""

import contextlib
import importlib
import sys


class MissingModule(ImportError):
    """A module the post-processing needs is not importable by this interpreter."""


def need(module, debian_package, interpreter="/usr/bin/python3"):
    """Imports `module`, or raises MissingModule naming the package and the interpreters."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingModule(
            f"{module} is missing in {sys.executable} (Python {sys.version.split()[0]}): install "
            f"Debian's {debian_package}, or run with {interpreter} where it is installed"
        ) from None


def need_or_exit(tool, module, debian_package, interpreter="/usr/bin/python3"):
    """need(), or for a script: the reason on stderr as `tool: ...` and exit status 2."""
    try:
        return need(module, debian_package, interpreter)
    except MissingModule as e:
        print(f"{tool}: {e}", file=sys.stderr)
        sys.exit(2)


@contextlib.contextmanager
def tool_errors(tool):
    """For a script's work: a missing module (MissingModule names the interpreter to use), a
    missing file, column or key, or a bad value ends it with `tool: reason` on stderr and exit
    status 2 instead of a traceback."""
    try:
        yield
    except ImportError as e:
        print(f"{tool}: {e}", file=sys.stderr)
        sys.exit(2)
    except (OSError, KeyError, ValueError) as e:
        print(f"{tool}: {e.args[0] if e.args else e}", file=sys.stderr)
        sys.exit(2)
