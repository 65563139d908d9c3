"""Command line: python3 -m ism_client [--server HOST:PORT] [--tls-ca CA.crt [--tls-cert C.crt --tls-key C.key]]
    recognize FILE.pcd|DEPTH.png [--preset default|seed] [--min-confidence P] [--up X,Y,Z] | models [NAME] | health

The token for a server started with --token-file comes from ISM_TOKEN (or --token, which shows
in ps). Exit status: 0 on success, 1 when the server answered an error (or health is not
SERVING; a failed TLS handshake is UNAVAILABLE), 2 for bad arguments or unreadable files."""
import argparse
import os
import sys

from google.protobuf import json_format

from . import KINECT, Intrinsics, IsmError, connect, read_pcd, service_pb2


def _print_result(result, as_json: bool):
    if as_json:
        print(json_format.MessageToJson(result, preserving_proto_field_name=True))
        return
    print(f"model {result.model_name}@{result.model_version}: {result.input_points} points, "
          f"{result.keypoints} keypoints, {len(result.hypotheses)} hypotheses, {result.total_ms:.1f} ms")
    if result.HasField("gravity"):
        print(f"  {gravity_line(result.gravity)}")
    for h in result.hypotheses:
        c = h.center
        print(f"  {h.category:<14} confidence {h.confidence:.3f}  score {h.score:8.3f} (threshold {h.threshold:.3f})  "
              f"centre ({c.x:.3f}, {c.y:.3f}, {c.z:.3f}) m  support {h.support}"
              f"{'' if h.passed_selection else '  [failed box selection]'}")
        for a in h.alternatives:
            print(f"    or {a.category:<11} confidence {a.confidence:.3f}")


def gravity_line(g) -> str:
    """Which up the boxes stand along, as ism-client prints it: a found floor or a guess."""
    source = service_pb2.UpSource.Name(g.source).replace("UP_SOURCE_", "").lower()
    line = f"up: ({g.up.x:.2f}, {g.up.y:.2f}, {g.up.z:.2f}) {source}"
    line += f", floor at {g.floor_level:.2f} m ({g.floor_points} points)" if g.HasField("floor_level") else \
        ", no floor found"
    if g.walls:
        line += f", {g.walls} walls ({g.wall_points} points)"
    return line


def _up(text: str):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"'{text}' is not three numbers X,Y,Z")
    return values


def _recognize(client, args):
    options = dict(model=args.model, categories=args.category or (), min_score=args.min_score,
                   max_hypotheses=args.max_hypotheses, preset=args.preset, min_confidence=args.min_confidence,
                   up=args.up)
    if args.file.lower().endswith(".png"):
        with open(args.file, "rb") as f:
            depth = f.read()
        intrinsics = Intrinsics(args.fx, args.fy, args.cx, args.cy, args.depth_scale)
        return client.recognize_depth(depth, intrinsics, **options)
    if args.file.lower().endswith(".pcd"):
        cloud = read_pcd(args.file)
        return client.recognize_cloud(cloud.points, cloud.rgb, width=cloud.width, height=cloud.height, **options)
    raise ValueError(f"{args.file}: expected a .pcd cloud or a 16-bit .png depth image")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m ism_client", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--server", default=os.environ.get("ISM_SERVER", "127.0.0.1:50051"),
                    help="gRPC target (default: $ISM_SERVER or 127.0.0.1:50051)")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per call")
    ap.add_argument("--json", action="store_true", help="print the full response as JSON")
    ap.add_argument("--tls", action="store_true",
                    help="connect with TLS, trusting the system's CAs (implied by the --tls-* options)")
    ap.add_argument("--tls-ca", default=os.environ.get("ISM_TLS_CA") or None,
                    help="PEM CA certificates to trust instead of the system's (default: $ISM_TLS_CA)")
    ap.add_argument("--tls-cert", help="PEM client certificate, for servers that require one (mTLS); needs --tls-key")
    ap.add_argument("--tls-key", help="PEM private key of --tls-cert")
    ap.add_argument("--tls-server-name",
                    help="name to check the server certificate against (default: the host of --server)")
    ap.add_argument("--token", default=os.environ.get("ISM_TOKEN") or None,
                    help="bearer token sent as 'authorization: Bearer TOKEN' (default: $ISM_TOKEN; prefer it: "
                         "arguments show in ps)")
    sub = ap.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("recognize", help="recognize furniture in a .pcd cloud or a 16-bit .png depth image")
    rec.add_argument("file")
    rec.add_argument("--model", default="", help="model name (default: the server's default)")
    rec.add_argument("--category", action="append", help="only this category (repeatable)")
    rec.add_argument("--min-score", type=float, help="override the model's detection threshold")
    rec.add_argument("--max-hypotheses", type=int, default=0)
    rec.add_argument("--preset", choices=("default", "seed"),
                     help="default: calibrated confidence, one answer per object; seed: the seed's pipeline")
    rec.add_argument("--min-confidence", type=float,
                     help="default preset: drop hypotheses less confident (server default 0.3; at most 0.99)")
    rec.add_argument("--up", type=_up, metavar="X,Y,Z",
                     help="the scene's up in its coordinates, when known (default: the server finds the floor)")
    for name, default in (("fx", KINECT.fx), ("fy", KINECT.fy), ("cx", KINECT.cx), ("cy", KINECT.cy),
                          ("depth-scale", KINECT.depth_scale)):
        rec.add_argument(f"--{name}", type=float, default=default, help=f"depth PNG intrinsics (default {default})")
    models = sub.add_parser("models", help="list the loaded models, or show one")
    models.add_argument("name", nargs="?")
    sub.add_parser("health", help="grpc.health.v1 check; exit 0 only when SERVING")
    args = ap.parse_args(argv)
    if bool(args.tls_cert) != bool(args.tls_key):
        ap.error("--tls-cert and --tls-key go together")

    try:
        with connect(args.server, timeout=args.timeout, tls=args.tls, tls_ca=args.tls_ca, tls_cert=args.tls_cert,
                     tls_key=args.tls_key, tls_server_name=args.tls_server_name, token=args.token) as client:
            if args.command == "health":
                status = client.health()
                print(status)
                return 0 if status == "SERVING" else 1
            if args.command == "models":
                infos = [client.get_model(args.name)] if args.name else client.list_models()
                for info in infos:
                    if args.json:
                        print(json_format.MessageToJson(info, preserving_proto_field_name=True))
                    else:
                        categories = ", ".join(c.name for c in info.categories)
                        print(f"{info.name}@{info.version}  {info.path}  [{categories}]")
                return 0
            _print_result(_recognize(client, args), args.json)
            return 0
    except IsmError as e:
        print(f"error from {args.server}: {e}", file=sys.stderr)
        return 1
    except (OSError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
