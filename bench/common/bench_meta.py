"""What the Python benches record beside their figures: the machine and the commit measured.

The C++ benches' twin is bench/common/bench_report.cpp."""

import os
import shlex
import subprocess


def sh(cmd):
    return subprocess.run(cmd, shell=True, capture_output=True, text=True).stdout.strip()


def machine(with_gpu=False, with_load=False):
    """The CPU and its hardware threads; the GPU's name where one is asked for and found, the
    1-minute load average where asked for (a shared machine's figures depend on it)."""
    cpu = sh("grep -m1 'model name' /proc/cpuinfo | cut -d: -f2").strip() or "unknown CPU"
    text = f"{cpu}, {os.cpu_count()} hardware threads"
    if with_gpu:
        gpu = sh("nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null")
        text += f", GPU {gpu}" if gpu else ""
    if with_load:
        text += f", load {os.getloadavg()[0]:.2f}"
    return text


def commit(source):
    """The source tree's short commit, with -dirty when tracked files differ from it."""
    c = sh(f"git -C {shlex.quote(str(source))} rev-parse --short HEAD 2>/dev/null")
    if not c:
        return "unknown"
    dirty = sh(f"git -C {shlex.quote(str(source))} status --porcelain --untracked-files=no")
    return c + ("-dirty" if dirty else "")
