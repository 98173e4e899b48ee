"""For the tests/system checks that need an optional Python module (matplotlib): the module,
or a line saying which Debian package is missing and exit status 77 (ctest's
SKIP_RETURN_CODE: skipped, not passed)."""
import importlib
import sys

SKIP = 77


def module_or_skip(module, debian_package):
    try:
        return importlib.import_module(module)
    except ImportError:
        print(f"{module} is not installed (Debian: {debian_package}): skipped")
        sys.exit(SKIP)
