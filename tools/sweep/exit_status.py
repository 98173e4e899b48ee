"""demfem's exit statuses, read from the one C++ header that defines them
(protocol/interface/include/demfem/interface/exit_status.hpp): the sweep does not keep a copy.
Each `inline constexpr int kExitName = N;  ///< short name: meaning` line there becomes
EXIT_NAME = N here, and the short name is what describe_exit prints ("exit 3 (blow-up)").
A kExit line in another form is refused (HeaderError) rather than skipped, so that a code
added to the header cannot go missing here."""

import re
from pathlib import Path

HEADER = (Path(__file__).resolve().parents[2] / "protocol" / "interface" / "include" / "demfem"
          / "interface" / "exit_status.hpp")
_NAMESPACE = re.compile(r"^namespace ([A-Za-z_:]+) \{")
_CODE = re.compile(r"^inline constexpr int kExit([A-Za-z]+) = (\d+);\s*///< ([^:]+):")
RUN_NAMESPACE = "demfem"  # the run's codes: demfem_run, dem_server, fem_server, the sweep


class HeaderError(ValueError):
    pass


def _snake(camel):
    return re.sub(r"(?<!^)(?=[A-Z])", "_", camel).upper()


def read_header(text, where=str(HEADER)):
    """{namespace: {"EXIT_NAME": (code, short name)}} of every kExit constant in `text`."""
    codes, namespace = {}, None
    for number, line in enumerate(text.splitlines(), 1):
        opened = _NAMESPACE.match(line)
        if opened:
            namespace = opened.group(1)
            continue
        if "kExit" not in line or not re.match(r"^\s*(inline )?(static )?constexpr", line):
            continue
        code = _CODE.match(line)
        if not code or namespace is None:
            raise HeaderError(f"{where}:{number}: an exit status not in the form "
                              "`inline constexpr int kExitName = N;  ///< short name: meaning` "
                              f"inside a namespace: {line.strip()}")
        table = codes.setdefault(namespace, {})
        table["EXIT_" + _snake(code.group(1))] = (int(code.group(2)), code.group(3).strip())
    if RUN_NAMESPACE not in codes:
        raise HeaderError(f"{where}: no exit status in namespace {RUN_NAMESPACE}")
    return codes


CODES = read_header(HEADER.read_text(encoding="utf-8"))
RUN_CODES = CODES[RUN_NAMESPACE]
NAMES = {code: name for code, name in RUN_CODES.values()}  # e.g. 3: "blow-up"

EXIT_FAILED = RUN_CODES["EXIT_FAILED"][0]
EXIT_BAD_INPUT = RUN_CODES["EXIT_BAD_INPUT"][0]
EXIT_BLOW_UP = RUN_CODES["EXIT_BLOW_UP"][0]
EXIT_RECOVERY_EXHAUSTED = RUN_CODES["EXIT_RECOVERY_EXHAUSTED"][0]
EXIT_NOT_STARTED = RUN_CODES["EXIT_NOT_STARTED"][0]
