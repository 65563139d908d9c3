"""Small synthetic scenes and file writers shared by the Python client and scale-out tests: a
floor with a table-sized box on it, as a cloud, a depth image, a 16-bit PNG and PCD files."""
import struct
import zlib

import numpy as np

# A 160x120 Kinect-like camera (the 640x480 intrinsics scaled by 1/4) keeps requests small.
SMALL_CAMERA = dict(fx=131.25, fy=131.25, cx=79.5, cy=59.5, depth_scale=1000.0)


def box_on_floor(step: float = 0.02, seed: int = 7) -> np.ndarray:
    """(N, 3) float32 metres, z up: a 1.6 x 1.6 m floor and the top and sides of a
    0.8 x 0.5 x 0.75 m box, with 2 mm of noise."""
    g = np.arange(-0.8, 0.8, step)
    fx, fy = np.meshgrid(g, g)
    parts = [np.stack([fx.ravel(), fy.ravel(), np.zeros(fx.size)], axis=1)]
    bx, by, bz = np.arange(-0.4, 0.4, step), np.arange(-0.25, 0.25, step), np.arange(0, 0.75, step)
    tx, ty = np.meshgrid(bx, by)
    parts.append(np.stack([tx.ravel(), ty.ravel(), np.full(tx.size, 0.75)], axis=1))
    for x in (-0.4, 0.4):
        sy, sz = np.meshgrid(by, bz)
        parts.append(np.stack([np.full(sy.size, x), sy.ravel(), sz.ravel()], axis=1))
    for y in (-0.25, 0.25):
        sx, sz = np.meshgrid(bx, bz)
        parts.append(np.stack([sx.ravel(), np.full(sx.size, y), sz.ravel()], axis=1))
    points = np.concatenate(parts)
    points += np.random.default_rng(seed).normal(0, 0.002, points.shape)
    return points.astype(np.float32)


def depth_of_box(width: int = 160, height: int = 120) -> np.ndarray:
    """HxW uint16 millimetres: a wall at 2.5 m and a box face at 1.6 m in the middle."""
    depth = np.full((height, width), 2500, dtype=np.uint16)
    depth[height // 3: 2 * height // 3, width // 3: 2 * width // 3] = 1600
    depth[:4, :] = 0  # invalid pixels, as real sensors have at the border
    return depth


def png16(depth: np.ndarray) -> bytes:
    """A 16-bit greyscale PNG (big-endian samples, filter 0 on every row)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    h, w = depth.shape
    rows = b"".join(b"\x00" + row.astype(">u2").tobytes() for row in depth)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def lzf_literals(data: bytes) -> bytes:
    """Valid LZF made only of literal runs (at most 32 bytes each): enough to exercise a reader."""
    return b"".join(bytes([len(data[i:i + 32]) - 1]) + data[i:i + 32] for i in range(0, len(data), 32))


def write_pcd(path: str, points: np.ndarray, rgb=None, kind: str = "binary"):
    n = len(points)
    fields = [("x", points[:, 0]), ("y", points[:, 1]), ("z", points[:, 2])]
    if rgb is not None:
        packed = (rgb[:, 0].astype(np.uint32) << 16) | (rgb[:, 1].astype(np.uint32) << 8) | rgb[:, 2]
        fields.append(("rgb", packed.astype("<u4").view("<f4")))
    names = " ".join(name for name, _ in fields)
    header = (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\n"
              f"SIZE {' '.join('4' * len(fields))}\nTYPE {' '.join('F' * len(fields))}\n"
              f"COUNT {' '.join('1' * len(fields))}\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
              f"POINTS {n}\nDATA {kind}\n")
    columns = np.stack([v.astype("<f4") for _, v in fields], axis=1)
    if kind == "ascii":
        lines = []
        for row, bits in zip(columns, columns.view("<u4")):
            values = [repr(float(v)) for v in row[:3]] + ([str(int(bits[3]))] if rgb is not None else [])
            lines.append(" ".join(values))
        body = ("\n".join(lines) + "\n").encode()
    elif kind == "binary":
        body = columns.tobytes()
    else:  # binary_compressed: field by field, then LZF
        planar = np.ascontiguousarray(columns.T).tobytes()
        compressed = lzf_literals(planar)
        body = struct.pack("<II", len(compressed), len(planar)) + compressed
    with open(path, "wb") as f:
        f.write(header.encode() + body)
