#!/usr/bin/env python3
"""Writes the seed corpora in corpus/<target>/: small valid inputs of each format (and a few
near-misses) for libFuzzer to mutate. Protobuf seeds are encoded by protoc from text format.
Usage: make_corpus.py [PROTOC]  (run from anywhere; rewrites the files in place)"""
import os
import struct
import subprocess
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_DIR = os.path.join(HERE, "..", "..", "proto")
PROTOC = sys.argv[1] if len(sys.argv) > 1 else "protoc"


def write(target, name, data):
    folder = os.path.join(HERE, "corpus", target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def encode(message, text):
    return subprocess.run([PROTOC, "--proto_path=" + PROTO_DIR, "--encode=ism.v1." + message,
                           "ism/v1/service.proto"], input=text.encode(), check=True,
                          capture_output=True).stdout


# A 3x2 organized scene: a tilted plane with one missing pixel, in metres.
GRID_W, GRID_H = 3, 2
POINTS = [(0.1 * c, 0.1 * r, 1.0 + 0.05 * c) for r in range(GRID_H) for c in range(GRID_W)]
COLOURS = [(200, 30 * i, 10) for i in range(len(POINTS))]


def pcd_header(fields, sizes, types, data, width, height, points):
    return (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\nSIZE {sizes}\n"
            f"TYPE {types}\nCOUNT {' '.join('1' * len(fields.split()))}\nWIDTH {width}\nHEIGHT {height}\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n")


def rgb_float(r, g, b):
    return struct.unpack("<f", struct.pack("<I", (r << 16) | (g << 8) | b))[0]


def lzf_literal(raw):
    # LZF with literal runs only (control byte n < 32: n+1 literal bytes follow): valid input for
    # PCL's decompressor without implementing the back-references.
    out = bytearray()
    for i in range(0, len(raw), 32):
        chunk = raw[i:i + 32]
        out += bytes([len(chunk) - 1]) + chunk
    return bytes(out)


def pcd_seeds():
    n = len(POINTS)
    body = "".join(f"{x} {y} {z}\n" for x, y, z in POINTS[:-1]) + "nan nan nan\n"
    write("pcd", "ascii_xyz_organized.pcd", pcd_header("x y z", "4 4 4", "F F F", "ascii", GRID_W, GRID_H, n) + body)
    body = "".join(f"{x} {y} {z} {rgb_float(*c)!r}\n" for (x, y, z), c in zip(POINTS, COLOURS))
    write("pcd", "ascii_xyzrgb.pcd", pcd_header("x y z rgb", "4 4 4 4", "F F F F", "ascii", n, 1, n) + body)
    packed = b"".join(struct.pack("<3fI", *p, (r << 16) | (g << 8) | b) for p, (r, g, b) in zip(POINTS, COLOURS))
    write("pcd", "binary_xyzrgb.pcd",
          pcd_header("x y z rgb", "4 4 4 4", "F F F U", "binary", GRID_W, GRID_H, n).encode() + packed)
    # binary_compressed stores each field as its own column.
    columns = b"".join(struct.pack(f"<{n}f", *[p[i] for p in POINTS]) for i in range(3))
    compressed = lzf_literal(columns)
    write("pcd", "binary_compressed_xyz.pcd",
          pcd_header("x y z", "4 4 4", "F F F", "binary_compressed", n, 1, n).encode() +
          struct.pack("<II", len(compressed), len(columns)) + compressed)
    write("pcd", "header_only.pcd", pcd_header("x y z", "4 4 4", "F F F", "ascii", 0, 1, 0))


def ply_seeds():
    n = len(POINTS)
    head = "ply\nformat {}\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n"
    colour = "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    write("ply", "ascii_xyz.ply", head.format("ascii 1.0", n) + "end_header\n" +
          "".join(f"{x} {y} {z}\n" for x, y, z in POINTS))
    write("ply", "ascii_xyzrgb_faces.ply", head.format("ascii 1.0", n) + colour +
          "element face 1\nproperty list uchar int vertex_indices\nend_header\n" +
          "".join(f"{x} {y} {z} {r} {g} {b}\n" for (x, y, z), (r, g, b) in zip(POINTS, COLOURS)) + "3 0 1 2\n")
    body = b"".join(struct.pack("<3f3B", *p, *c) for p, c in zip(POINTS, COLOURS))
    write("ply", "binary_le_xyzrgb.ply", (head.format("binary_little_endian 1.0", n) + colour + "end_header\n").encode() + body)
    body = b"".join(struct.pack(">3f", *p) for p in POINTS)
    write("ply", "binary_be_xyz.ply", (head.format("binary_big_endian 1.0", n) + "end_header\n").encode() + body)


def png(width, height, bit_depth, colour_type, rows):
    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))
    raw = b"".join(b"\0" + row for row in rows)  # filter type 0 on every row
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bit_depth, colour_type, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def depth_seeds():
    depth = [[1000 + 10 * c + 100 * r if (r, c) != (1, 2) else 0 for c in range(4)] for r in range(3)]
    write("depth_png", "gray16_4x3.png", png(4, 3, 16, 0, [struct.pack(">4H", *row) for row in depth]))
    write("depth_png", "gray8_4x3.png", png(4, 3, 8, 0, [bytes([10 * c + r for c in range(4)]) for r in range(3)]))
    write("depth_png", "rgb16_2x2.png", png(2, 2, 16, 2, [struct.pack(">6H", *range(6))] * 2))
    return png(4, 3, 16, 0, [struct.pack(">4H", *row) for row in depth])


def packed_seeds():
    xyz = b"".join(struct.pack("<3f", *p) for p in POINTS)
    rgb = b"".join(bytes(c) for c in COLOURS)
    write("packed", "organized_rgb.bin", struct.pack("<iiB", GRID_W, GRID_H, 1) + xyz + rgb)
    write("packed", "unorganized.bin", struct.pack("<iiB", len(POINTS), 1, 0) + xyz)
    nan = struct.pack("<3f", float("nan"), 0.0, float("inf"))
    write("packed", "organized_nan.bin", struct.pack("<iiB", 2, 2, 0) + xyz[:36] + nan)


MODEL_DATA = """
front_end { leaf_size: 0.02 normal_radius: 0.05 boundary_radius: 0.05 boundary_angle_threshold: 1.57
            shot_radius: 0.2 shot_min_neighbours: 5 keypoint_method: KEYPOINT_METHOD_AUTO contour_window: 2
            contour_min_jump: 0.05 contour_relative_jump: 0.02 contour_max_gap: 4 keypoint_min_spacing: 0.03 }
trained_knn { strategy: ACTIVATION_STRATEGY_KNN k: 2 }
trained_cutoff { strategy: ACTIVATION_STRATEGY_CUTOFF cutoff: 0.5 }
global_codebook { size: 2 dim: 3 centers: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6] }
categories {
  name: "chair" bin_size: 0.1
  box { min_volume: 0.1 max_volume: 0.5 max_edge: 1.2 mean_volume: 0.3 std_volume: 0.1 mean_max_edge: 0.9 std_max_edge: 0.1 }
  own_codebook { size: 1 dim: 3 centers: [0.2, 0.2, 0.2] }
  global_votes { offsets: [0, 1, 2] vectors: [0.1, 0.0, 0.3, -0.1, 0.2, 0.0] }
  own_votes { offsets: [0, 1] vectors: [0.0, 0.1, 0.2] }
  thresholds { codebook: CODEBOOK_TYPE_GLOBAL activation: ACTIVATION_STRATEGY_KNN weighting: VOTE_WEIGHTING_LOCALIZATION value: 1.5 mean: 2.0 std: 0.5 }
  training_models: 2 training_scans: 24
}
categories { name: "table" bin_size: 0.1 global_votes { offsets: [0, 0, 1] vectors: [0.0, 0.0, 0.4] } }
provenance { meshes: "chair\\tchair.obj\\tcredit" scans: 24 created: "2026-01-01" code_version: "seed" }
"""


def model_seeds():
    payload = encode("ModelData", MODEL_DATA)
    write("model", "payload.bin", b"\x01" + payload)
    envelope = encode("ModelFile", f'magic: "ISM-MODEL" format_version: 1 payload_crc32: {zlib.crc32(payload)}')
    # Appending the payload field by hand keeps the bytes exact (text format would escape them).
    envelope += b"\x1a" + varint(len(payload)) + payload
    write("model", "model_file.bin", b"\x00" + envelope)


def varint(n):
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | (0x80 if n else 0))
        if not n:
            return bytes(out)


def request_seeds(depth_png):
    def bytes_literal(data):
        return '"' + "".join(f"\\{b:03o}" for b in data) + '"'
    xyz = b"".join(struct.pack("<3f", *p) for p in POINTS)
    rgb = b"".join(bytes(c) for c in COLOURS)
    write("request", "cloud.bin", encode("RecognizeRequest", f"""request_id: "seed" scene {{ cloud {{
        xyz: {bytes_literal(xyz)} rgb: {bytes_literal(rgb)} width: {GRID_W} height: {GRID_H} }}
        sensor_origin {{ z: -1 }} sensor_orientation {{ w: 1 }} }} options {{ model: "default" }}"""))
    raw = struct.pack("<6H", 1000, 1010, 0, 1100, 1110, 1120)
    write("request", "depth_raw.bin", encode("RecognizeRequest", f"""scene {{ depth {{
        encoding: DEPTH_ENCODING_RAW_UINT16_LE data: {bytes_literal(raw)} width: 3 height: 2
        intrinsics {{ fx: 525 fy: 525 cx: 1 cy: 0.5 depth_scale: 1000 }} }} }}"""))
    write("request", "depth_png.bin", encode("RecognizeRequest", f"""scene {{ depth {{
        encoding: DEPTH_ENCODING_PNG data: {bytes_literal(depth_png)}
        intrinsics {{ fx: 525 fy: 525 cx: 1.5 cy: 1 depth_scale: 5000 }} }} }}"""))


pcd_seeds()
ply_seeds()
packed_seeds()
model_seeds()
request_seeds(depth_seeds())
