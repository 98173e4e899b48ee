"""The rules for text that the sweep writes into files that another program reads as code or
as options: the sbatch script (its `#SBATCH` lines are read by sbatch, the rest by bash) and
the paths of member folders. Each check returns a problem (a sentence for the message, the
caller names the key or option) or None; docs/sweeps.md ("Values written into the job
script") lists the rules. A newline in any of them would start a new line of the script:
a shell command."""

import re

_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
# Partitions, accounts and QOS are names (a comma separates several partitions or QOS).
_SLURM_NAME = re.compile(r"[A-Za-z0-9_.:@+-]+(,[A-Za-z0-9_.:@+-]+)*")
_SLURM_TIME = re.compile(r"(\d+-)?\d+(:\d+){0,2}")
_SLURM_MEM = re.compile(r"\d+[KMGTkmgt]?")
# One option as one word: -x, -xVALUE, --name or --name=VALUE. sbatch splits an #SBATCH line
# at blanks and reads quotes and backslashes itself, so none of them may be in it.
_SBATCH_OPTION = re.compile(r"(-[A-Za-z][^\s\"'\\]*|--[A-Za-z][A-Za-z0-9-]*(=[^\s\"'\\]+)?)")
# Options that the script sets itself for every array task (slurm.script_text).
SCRIPT_OPTIONS = {"--job-name": "-J", "--output": "-o", "--error": "-e", "--chdir": "-D",
                  "--ntasks": "-n", "--cpus-per-task": "-c", "--array": "-a"}
SLURM_VALUE_RULES = {
    "partition": (_SLURM_NAME, "a partition name, or several separated by commas (letters, "
                  "digits and _.:@+-)"),
    "account": (_SLURM_NAME, "an account name (letters, digits and _.:@+-)"),
    "qos": (_SLURM_NAME, "a QOS name, or several separated by commas (letters, digits and "
            "_.:@+-)"),
    "time": (_SLURM_TIME, 'a Slurm time such as "30", "2:00:00" or "1-12:00:00"'),
    "mem": (_SLURM_MEM, 'a Slurm size: an integer with an optional unit K, M, G or T, e.g. '
            '"8G"'),
}


def control_character(text):
    """A description of the first control character (newline, tab, NUL, ...) in `text`, or
    None."""
    m = _CONTROL.search(text)
    if not m:
        return None
    return f"contains the control character U+{ord(m.group()):04X} at offset {m.start()}"


def slurm_value_problem(name, value):
    """`name` is one of SLURM_VALUE_RULES ([slurm] keys and their command-line twins)."""
    if not value:
        return None
    pattern, what = SLURM_VALUE_RULES[name]
    if pattern.fullmatch(value):
        return None
    bad = control_character(value)
    return (f"is {value!r}" + (f", which {bad}" if bad else "") + f"; expected {what} (it is "
            f"written into the job script as #SBATCH --{name}=VALUE)")


def sbatch_option_problem(option):
    """One entry of [slurm] options or --sbatch-option."""
    bad = control_character(option)
    if bad or not _SBATCH_OPTION.fullmatch(option):
        return (f"{option!r} is not one sbatch option as one word ("
                + (f"it {bad}; " if bad else "") + "-x, -xVALUE, --name or --name=VALUE, "
                "without blanks, quotes or backslashes: it is written into the job script "
                "as an #SBATCH line)")
    name = option.split("=", 1)[0]
    for long, short in SCRIPT_OPTIONS.items():
        # sbatch takes an unambiguous prefix of a long option too (getopt_long).
        if (name.startswith("--") and long.startswith(name)) or \
                (not name.startswith("--") and name.startswith(short)):
            return (f"'{option}' sets {long}, which the sweep writes itself for every array "
                    "task (docs/sweeps.md)")
    return None


def script_path_problem(path):
    """A path written into an #SBATCH line (the sweep folder, the log pattern): sbatch splits
    those at blanks and reads quotes, backslashes and % patterns itself."""
    text = str(path)
    bad = control_character(text)
    if bad:
        return bad
    m = re.search(r"[\s\"'\\%]", text)
    if m:
        return (f"contains {m.group()!r}, which sbatch would read in an #SBATCH line (blanks "
                "split it, quotes and backslashes are removed, % starts a file name pattern)")
    return None
