"""The build backend (PEP 517) of demfem's Python SDK: `pip install protocol/python`.

Why not setuptools: pip isolates a build and would fetch setuptools and wheel from the
network; Debian's python3-setuptools works only for Debian's own python3 (it is patched), so
neither reaches every Python 3 on an offline machine. This backend needs nothing but the
standard library, a C++20 compiler (CXX, default g++; "ccache g++" works) and the headers of
the Python that runs pip (python3-dev for Debian's; pyenv and venvs bring their own), plus
pybind11's headers: the pybind11 module of that Python if it has one, else /usr/include
(Debian's pybind11-dev). It compiles the bindings (bindings.cpp) and the protocol library's
sources (../ipc/src) into demfem/_protocol<EXT_SUFFIX> for that interpreter, in parallel,
and writes a wheel holding it and demfem/*.py. The version is the CMake project's.

DEMFEM_SDK_BUILD_DIR: keep the object files there (default: a temporary folder, removed).
"""
import base64
import concurrent.futures
import hashlib
import os
import re
import shlex
import subprocess
import sys
import sysconfig
import tempfile
import tomllib
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PROTOCOL = os.path.dirname(HERE)
REPO = os.path.dirname(PROTOCOL)


def _version():
    path = os.path.join(REPO, "CMakeLists.txt")
    with open(path, encoding="utf-8") as f:
        m = re.search(r"project\(demfem VERSION ([0-9.]+)", f.read())
    if not m:
        raise RuntimeError(f"{path}: no 'project(demfem VERSION x.y.z' to take the version from")
    return m.group(1)


def _project():
    with open(os.path.join(HERE, "pyproject.toml"), "rb") as f:
        return tomllib.load(f)["project"]


def _pybind11_include():
    try:
        import pybind11
        return pybind11.get_include()
    except ImportError:
        if os.path.isfile("/usr/include/pybind11/pybind11.h"):
            return "/usr/include"
    raise RuntimeError("pybind11's headers are missing: install Debian's pybind11-dev, or the "
                       "pybind11 module into the Python that runs pip")


def _wheel_tag():
    """cpXY-cpXY<abiflags>-<platform>: the interpreter the extension is compiled for."""
    version = f"cp{sys.version_info.major}{sys.version_info.minor}"
    platform = re.sub(r"[-.]", "_", sysconfig.get_platform())
    return f"{version}-{version}{getattr(sys, 'abiflags', '')}-{platform}"


def _compile_extension(build_dir):
    """Compiles demfem._protocol into build_dir; returns the module's path."""
    cxx = shlex.split(os.environ.get("CXX", "g++"))
    python_include = sysconfig.get_paths()["include"]
    if not os.path.isfile(os.path.join(python_include, "Python.h")):
        raise RuntimeError(f"{python_include}/Python.h is missing: install this Python's "
                           "headers (Debian: python3-dev)")
    flags = ["-std=c++20", "-O2", "-fPIC", "-fvisibility=hidden", "-pthread",
             "-I" + os.path.join(PROTOCOL, "ipc", "include"),
             "-I" + os.path.join(PROTOCOL, "interface", "include"),
             "-I" + _pybind11_include(), "-I" + python_include]
    ipc_src = os.path.join(PROTOCOL, "ipc", "src")
    sources = [os.path.join(HERE, "bindings.cpp")] + sorted(
        os.path.join(ipc_src, f) for f in os.listdir(ipc_src) if f.endswith(".cpp"))

    def compile_one(source):
        obj = os.path.join(build_dir, os.path.basename(source) + ".o")
        r = subprocess.run(cxx + flags + ["-c", source, "-o", obj], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"compiling {source} failed:\n{r.stderr}")
        return obj

    jobs = min(len(sources), os.cpu_count() or 1)
    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        objects = list(pool.map(compile_one, sources))
    module = os.path.join(build_dir, "_protocol" + sysconfig.get_config_var("EXT_SUFFIX"))
    r = subprocess.run(cxx + ["-shared", "-pthread", *objects, "-o", module],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"linking {module} failed:\n{r.stderr}")
    return module


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _metadata():
    p = _project()
    lines = ["Metadata-Version: 2.1", f"Name: {p['name']}", f"Version: {_version()}",
             f"Summary: {p['description']}", f"Requires-Python: {p['requires-python']}"]
    lines += [f"Requires-Dist: {d}" for d in p.get("dependencies", [])]
    return "\n".join(lines) + "\n"


def _write_wheel(wheel_directory, module):
    name, version = _project()["name"], _version()
    tag = _wheel_tag()
    wheel_name = f"{name}-{version}-{tag}.whl"
    dist_info = f"{name}-{version}.dist-info"
    files = []
    package = os.path.join(HERE, "demfem")
    for f in sorted(os.listdir(package)):
        if f.endswith(".py"):
            with open(os.path.join(package, f), "rb") as fh:
                files.append((f"demfem/{f}", fh.read()))
    with open(module, "rb") as fh:
        files.append((f"demfem/{os.path.basename(module)}", fh.read()))
    files.append((f"{dist_info}/METADATA", _metadata().encode()))
    files.append((f"{dist_info}/WHEEL", (f"Wheel-Version: 1.0\nGenerator: demfem_build\n"
                                         f"Root-Is-Purelib: false\nTag: {tag}\n").encode()))
    record = [_record_line(n, d) for n, d in files] + [f"{dist_info}/RECORD,,"]
    files.append((f"{dist_info}/RECORD", ("\n".join(record) + "\n").encode()))
    path = os.path.join(wheel_directory, wheel_name)
    # Written whole, then renamed: a failed build leaves no wheel that looks complete.
    with zipfile.ZipFile(path + ".part", "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in files:
            z.writestr(n, d)
    os.replace(path + ".part", path)
    return wheel_name


# ---- PEP 517 hooks -----------------------------------------------------------------------

def get_requires_for_build_wheel(config_settings=None):
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    keep = os.environ.get("DEMFEM_SDK_BUILD_DIR")
    if keep:
        os.makedirs(keep, exist_ok=True)
        return _write_wheel(wheel_directory, _compile_extension(keep))
    with tempfile.TemporaryDirectory(prefix="demfem-sdk-build-") as tmp:
        return _write_wheel(wheel_directory, _compile_extension(tmp))
