"""NRRD files as umbra writes them (`umbra synth`, `convert`, `resample`, `sweep`): a header
and the raw little-endian samples attached, components fastest. One reader and one writer for
the bench/ scripts; anything else (detached data, compressed encodings, big-endian) is refused
with a message naming the file and the field."""
from pathlib import Path

import numpy as np

TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uint8": "u1",
         "uchar": "u1", "unsigned char": "u1", "int8": "i1", "signed char": "i1",
         "int16": "<i2", "short": "<i2", "uint16": "<u2", "ushort": "<u2",
         "unsigned short": "<u2", "int32": "<i4", "int": "<i4", "uint32": "<u4",
         "unsigned int": "<u4", "int64": "<i8", "uint64": "<u8"}


def read(path, scalar=False):
    """(samples as float32, indexed [z, y, x] or [z, y, x, component], spacing x, y, z) of
    `path`; `scalar`: refuse a field of several components."""
    data = Path(path).read_bytes()
    head, sep, body = data.partition(b"\n\n")
    if not sep or not head.startswith(b"NRRD"):
        raise SystemExit(f"{path}: not an NRRD file with attached data")
    fields = {}
    for line in head.decode(errors="replace").splitlines()[1:]:
        if ":" in line and not line.startswith("#"):
            k, v = line.split(":", 1)
            fields[k.strip()] = v.strip()
    for key, ok in (("type", fields.get("type") in TYPES),
                    ("encoding", fields.get("encoding") == "raw"),
                    ("endian", fields.get("endian", "little") == "little"
                     or TYPES.get(fields.get("type"), "<")[0] != "<"),
                    ("data file", "data file" not in fields)):
        if not ok:
            raise SystemExit(f"{path}: field '{key}' is {fields.get(key)!r}: only raw "
                             "little-endian samples attached to the header are read here")
    sizes = [int(x) for x in fields["sizes"].split()]
    dim = len(sizes)
    if dim not in (3, 4) or (scalar and dim != 3):
        raise SystemExit(f"{path}: field 'dimension' is {dim}: a field of one component on a "
                         "3-D grid is needed (umbra convert --field NAME)")
    spatial = [s for s in fields.get("space directions", "").split(")") if "(" in s][:3]
    if len(spatial) == 3:
        spacing = [float(np.linalg.norm([float(c) for c in d.split("(")[1].split(",")]))
                   for d in spatial]
    else:
        spacing = [float(x) for x in fields.get("spacings", "1 1 1").split()][-3:]
    dt = np.dtype(TYPES[fields["type"]])
    n = int(np.prod(sizes))
    if len(body) < n * dt.itemsize:
        raise SystemExit(f"{path}: {len(body)} bytes of samples, {n * dt.itemsize} expected")
    a = np.frombuffer(body[: n * dt.itemsize], dtype=dt).astype(np.float32)
    return a.reshape(sizes[::-1]), spacing


def write(path, vol_zyx, spacing_xyz):
    """float32 NRRD, x fastest (the array is indexed [z, y, x])."""
    nz, ny, nx = vol_zyx.shape
    hdr = (
        "NRRD0004\ntype: float\ndimension: 3\n"
        f"sizes: {nx} {ny} {nz}\n"
        f"spacings: {spacing_xyz[0]!r} {spacing_xyz[1]!r} {spacing_xyz[2]!r}\n"
        "encoding: raw\nendian: little\n\n"
    )
    with open(path, "wb") as f:
        f.write(hdr.encode())
        f.write(np.ascontiguousarray(vol_zyx, dtype="<f4").tobytes())
