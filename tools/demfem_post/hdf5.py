"""Datasets of demfem's HDF5 files as numpy arrays, through the HDF5 C library that demfem
itself links (Debian's libhdf5 serial, by ctypes), so that reading fields needs no h5py.

Only what demfem writes is read: contiguous or chunked datasets of 8-byte floats or integers
(float64 and int64 arrays come back). The library is found as $DEMFEM_HDF5_LIBRARY, else
libhdf5_serial, else libhdf5; without it, MissingModule names Debian's libhdf5-dev."""

import ctypes
import ctypes.util
import os

from .needs import MissingModule, need

_H5F_ACC_RDONLY = 0
_H5P_DEFAULT = 0
_H5S_ALL = 0
_H5T_INTEGER, _H5T_FLOAT = 0, 1
_lib = None


def _library():
    global _lib
    if _lib is not None:
        return _lib
    names = [os.environ.get("DEMFEM_HDF5_LIBRARY"), ctypes.util.find_library("hdf5_serial"),
             ctypes.util.find_library("hdf5")]
    for name in filter(None, names):
        try:
            lib = ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        raise MissingModule("the HDF5 C library (libhdf5) is not found: install Debian's "
                            "libhdf5-dev (demfem's build needs it too), or set "
                            "DEMFEM_HDF5_LIBRARY to its path")
    hid, herr = ctypes.c_int64, ctypes.c_int
    lib.H5open.restype = herr
    lib.H5Fopen.argtypes = [ctypes.c_char_p, ctypes.c_uint, hid]
    lib.H5Fopen.restype = hid
    lib.H5Dopen2.argtypes = [hid, ctypes.c_char_p, hid]
    lib.H5Dopen2.restype = hid
    for f in ("H5Dget_space", "H5Dget_type"):
        getattr(lib, f).argtypes = [hid]
        getattr(lib, f).restype = hid
    lib.H5Tget_class.argtypes = [hid]
    lib.H5Tget_class.restype = ctypes.c_int
    lib.H5Sget_simple_extent_ndims.argtypes = [hid]
    lib.H5Sget_simple_extent_ndims.restype = ctypes.c_int
    lib.H5Sget_simple_extent_dims.argtypes = [hid, ctypes.POINTER(ctypes.c_uint64),
                                              ctypes.c_void_p]
    lib.H5Sget_simple_extent_dims.restype = ctypes.c_int
    lib.H5Dread.argtypes = [hid, hid, hid, hid, hid, ctypes.c_void_p]
    lib.H5Dread.restype = herr
    lib.H5Lexists.argtypes = [hid, ctypes.c_char_p, hid]
    lib.H5Lexists.restype = ctypes.c_int
    for f in ("H5Tclose", "H5Sclose", "H5Dclose", "H5Fclose"):
        getattr(lib, f).argtypes = [hid]
        getattr(lib, f).restype = herr
    lib.H5Eset_auto2.argtypes = [hid, ctypes.c_void_p, ctypes.c_void_p]
    if lib.H5open() < 0:
        raise OSError("the HDF5 library did not start (H5open)")
    lib.H5Eset_auto2(0, None, None)  # errors come back as values, printed by us, not by HDF5
    _lib = lib
    return lib


def read_dataset(path, name):
    """Dataset `name` (e.g. '/position') of HDF5 file `path` as a numpy array (float64 or
    int64, the dataset's shape). FileNotFoundError / KeyError / ValueError naming file and
    dataset."""
    np = need("numpy", "python3-numpy")
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such file")
    lib = _library()
    f = lib.H5Fopen(os.fsencode(path), _H5F_ACC_RDONLY, _H5P_DEFAULT)
    if f < 0:
        raise ValueError(f"{path}: not an HDF5 file HDF5 can open")
    try:
        return _read(lib, np, f, path, name)
    finally:
        lib.H5Fclose(f)


def _read(lib, np, f, path, name):
    parts = [p for p in name.split("/") if p]
    for k in range(1, len(parts) + 1):  # each link on the way must exist (H5Lexists' rule)
        if lib.H5Lexists(f, ("/" + "/".join(parts[:k])).encode(), _H5P_DEFAULT) <= 0:
            raise KeyError(f"{path}: no dataset {name}")
    d = lib.H5Dopen2(f, name.encode(), _H5P_DEFAULT)
    if d < 0:
        raise KeyError(f"{path}: {name} is not a dataset")
    space = tp = -1
    try:
        space, tp = lib.H5Dget_space(d), lib.H5Dget_type(d)
        rank = lib.H5Sget_simple_extent_ndims(space)
        dims = (ctypes.c_uint64 * max(rank, 1))()
        lib.H5Sget_simple_extent_dims(space, dims, None)
        shape = tuple(dims[k] for k in range(rank))
        kind = lib.H5Tget_class(tp)
        if kind == _H5T_FLOAT:
            out, memory = np.empty(shape, dtype=np.float64), "H5T_NATIVE_DOUBLE_g"
        elif kind == _H5T_INTEGER:
            out, memory = np.empty(shape, dtype=np.int64), "H5T_NATIVE_LLONG_g"
        else:
            raise ValueError(f"{path}: {name} holds neither floats nor integers")
        mem_type = ctypes.c_int64.in_dll(lib, memory).value
        if out.size and lib.H5Dread(d, mem_type, _H5S_ALL, _H5S_ALL, _H5P_DEFAULT,
                                    out.ctypes.data) < 0:
            raise ValueError(f"{path}: {name} could not be read")
        return out
    finally:
        if tp >= 0:
            lib.H5Tclose(tp)
        if space >= 0:
            lib.H5Sclose(space)
        lib.H5Dclose(d)
