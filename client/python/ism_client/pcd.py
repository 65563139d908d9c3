"""Reads PCD files (PCL's point cloud format: ascii, binary and binary_compressed) into numpy
arrays, so that the command line can send a .pcd without PCL installed."""
import dataclasses
from typing import Optional

import numpy as np

_TYPES = {("F", 4): "<f4", ("F", 8): "<f8", ("U", 1): "u1", ("U", 2): "<u2", ("U", 4): "<u4",
          ("I", 1): "i1", ("I", 2): "<i2", ("I", 4): "<i4"}


@dataclasses.dataclass
class Cloud:
    points: np.ndarray             # (N, 3) float32, metres
    rgb: Optional[np.ndarray]      # (N, 3) uint8, or None
    width: int                     # organized: width * height == N; unorganized: 0, 0
    height: int


def lzf_decompress(data: bytes, size: int) -> bytes:
    """liblzf's format, which PCL uses for DATA binary_compressed."""
    out = bytearray()
    i = 0
    while i < len(data):
        ctrl = data[i]
        i += 1
        if ctrl < 32:  # literal run of ctrl + 1 bytes
            out += data[i:i + ctrl + 1]
            i += ctrl + 1
            continue
        length = ctrl >> 5
        if length == 7:
            length += data[i]
            i += 1
        ref = len(out) - ((ctrl & 0x1F) << 8) - data[i] - 1
        i += 1
        if ref < 0:
            raise ValueError("corrupt LZF data (back reference before the start)")
        for _ in range(length + 2):  # byte by byte: the reference may overlap the output
            out.append(out[ref])
            ref += 1
    if len(out) != size:
        raise ValueError(f"LZF data decompressed to {len(out)} bytes, header says {size}")
    return bytes(out)


def read_pcd(path: str) -> Cloud:
    with open(path, "rb") as f:
        raw = f.read()
    header, offset = {}, 0
    while "DATA" not in header:
        end = raw.find(b"\n", offset)
        if end < 0:
            raise ValueError(f"{path}: not a PCD file (no DATA line in the header)")
        line = raw[offset:end].decode("ascii", "replace").strip()
        offset = end + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key.upper()] = values
    try:
        # PCL names padding fields "_", possibly several times: numpy needs unique names.
        fields = [f if f != "_" else f"_pad{i}" for i, f in enumerate(header["FIELDS"])]
        sizes = [int(s) for s in header["SIZE"]]
        types = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(fields))]
        width, height = int(header["WIDTH"][0]), int(header.get("HEIGHT", ["1"])[0])
        dtype = np.dtype([(name, _TYPES[(t, s)]) if c == 1 else (name, _TYPES[(t, s)], (c,))
                          for name, s, t, c in zip(fields, sizes, types, counts)])
    except (KeyError, ValueError, IndexError) as e:
        raise ValueError(f"{path}: malformed PCD header ({e!r})") from None
    n = width * height
    kind = header["DATA"][0].lower()
    body = raw[offset:]
    if kind == "ascii":
        table = np.loadtxt(body.decode("ascii").splitlines(), dtype=np.float64, ndmin=2)
        data = np.zeros(len(table), dtype=dtype)
        column = 0
        for name, c in zip(fields, counts):
            values = table[:, column:column + c]
            if name in ("rgb", "rgba") and dtype[name] == np.float32 and np.all(values == np.floor(values)):
                # PCL writes a packed float colour as the integer of its bits.
                data[name] = values[:, 0].astype(np.uint32).view(np.float32)
            else:
                data[name] = values[:, 0] if c == 1 else values
            column += c
    elif kind == "binary":
        if len(body) < n * dtype.itemsize:
            raise ValueError(f"{path}: truncated PCD ({len(body)} data bytes for {n} points of {dtype.itemsize})")
        data = np.frombuffer(body, dtype=dtype, count=n)
    elif kind == "binary_compressed":
        compressed, size = np.frombuffer(body[:8], dtype="<u4")
        # Stored field by field (all x, then all y...), not point by point.
        planar = lzf_decompress(body[8:8 + int(compressed)], int(size))
        data, start = np.zeros(n, dtype=dtype), 0
        for name in fields:
            field = dtype[name]
            values = np.frombuffer(planar, dtype=field.base, count=n * field.itemsize // field.base.itemsize,
                                   offset=start)
            data[name] = values.reshape(data[name].shape)
            start += n * field.itemsize
    else:
        raise ValueError(f"{path}: unknown PCD DATA kind {kind!r}")
    if len(data) != n:
        raise ValueError(f"{path}: header says {n} points, data holds {len(data)}")
    if not {"x", "y", "z"} <= set(fields):
        raise ValueError(f"{path}: PCD has no x, y, z fields (has {', '.join(fields)})")
    points = np.stack([data["x"], data["y"], data["z"]], axis=1).astype(np.float32)
    rgb = None
    colour = next((f for f in ("rgb", "rgba") if f in fields), None)
    if colour:
        # PCL packs colour as 0x00RRGGBB into the bytes of a float32 (or uint32) field.
        packed = np.ascontiguousarray(data[colour]).view("<u4")
        rgb = np.stack([(packed >> 16) & 0xFF, (packed >> 8) & 0xFF, packed & 0xFF], axis=1).astype(np.uint8)
    organized = height > 1
    return Cloud(points, rgb, width if organized else 0, height if organized else 0)
