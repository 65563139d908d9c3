"""A thin, typed wrapper around the ism.v1.FurnitureRecognizer gRPC service.

Results are the protobuf messages of the contract (ism.v1.RecognitionResult, ism.v1.ModelInfo,
ism.v1.FrameResult), so every field documented in proto/ism/v1/service.proto is available.
"""
import dataclasses
import json
from typing import Iterable, Iterator, Optional, Sequence

import grpc
import numpy as np

from ._stubs import health_pb2, health_pb2_grpc, model_pb2, service_pb2, service_pb2_grpc

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

_POLICIES = {
    "every_frame": service_pb2.BACKPRESSURE_POLICY_EVERY_FRAME,
    "latest_frame_wins": service_pb2.BACKPRESSURE_POLICY_LATEST_FRAME_WINS,
}
_CODEBOOKS = {"global": model_pb2.CODEBOOK_TYPE_GLOBAL, "separated": model_pb2.CODEBOOK_TYPE_SEPARATED}
_ACTIVATIONS = {"knn": model_pb2.ACTIVATION_STRATEGY_KNN, "cutoff": model_pb2.ACTIVATION_STRATEGY_CUTOFF}
_PRESETS = {"default": service_pb2.RECOGNITION_PRESET_DEFAULT, "seed": service_pb2.RECOGNITION_PRESET_SEED}
_WEIGHTINGS = {
    "categorization": model_pb2.VOTE_WEIGHTING_CATEGORIZATION,
    "localization": model_pb2.VOTE_WEIGHTING_LOCALIZATION,
    "activation": model_pb2.VOTE_WEIGHTING_ACTIVATION,
}


class IsmError(Exception):
    """A failed call: `code` is the grpc.StatusCode the server (or the channel) answered."""

    def __init__(self, code: grpc.StatusCode, message: str):
        super().__init__(f"{code.name}: {message}")
        self.code = code
        self.message = message


@dataclasses.dataclass
class Intrinsics:
    """Pinhole intrinsics of a depth image; depth_scale = raw units per metre (1000: millimetres)."""

    fx: float
    fy: float
    cx: float
    cy: float
    depth_scale: float = 1000.0

    def to_proto(self):
        return service_pb2.CameraIntrinsics(fx=self.fx, fy=self.fy, cx=self.cx, cy=self.cy,
                                            depth_scale=self.depth_scale)


# Microsoft Kinect / Asus Xtion at 640x480, OpenNI millimetres: the seed's sensor.
KINECT = Intrinsics(fx=525.0, fy=525.0, cx=319.5, cy=239.5, depth_scale=1000.0)


@dataclasses.dataclass
class Frame:
    """One frame of a stream: either `points` (+ optional `rgb`) or `depth` + `intrinsics`."""

    points: object = None
    rgb: object = None
    depth: object = None
    intrinsics: Optional[Intrinsics] = None
    frame_id: Optional[int] = None  # None: numbered 0, 1, 2... in sending order
    timestamp_us: int = 0
    up: Optional[Sequence[float]] = None  # this frame's up (x, y, z), when known: see cloud_scene()


def _to_bytes(array, dtype: str, columns: int, what: str):
    """Packs a numpy array or nested lists as little-endian `dtype`; returns (bytes, row count)."""
    a = np.asarray(array, dtype=dtype)
    if a.ndim != 2 or a.shape[1] != columns:
        raise ValueError(f"{what} must have shape (N, {columns}), got {a.shape}")
    return np.ascontiguousarray(a).tobytes(), a.shape[0]


def _vector(value, what: str):
    a = np.asarray(value, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{what} must be three numbers (x, y, z), got shape {a.shape}")
    return tuple(float(v) for v in a)


def _set_up(scene, up):
    """Scene.up from three numbers; the server checks that they make a direction (finite, not zero)."""
    if up is not None:
        x, y, z = _vector(up, "up")
        scene.up.SetInParent()  # present even when all zero: the server is to refuse that, not ignore it
        scene.up.x, scene.up.y, scene.up.z = x, y, z
    return scene


def cloud_scene(points, rgb=None, width: int = 0, height: int = 0, up=None):
    """ism.v1.Scene from Nx3 points in metres (+ optional Nx3 uint8 colours). `up`: the scene's up
    (x, y, z) in the points' frame when known (a z-up room scan: (0, 0, 1)); else the server looks
    for the floor."""
    xyz, n = _to_bytes(points, "<f4", 3, "points")
    cloud = service_pb2.PointCloud(xyz=xyz, width=width, height=height)
    if rgb is not None:
        cloud.rgb, n_rgb = _to_bytes(rgb, "u1", 3, "rgb")
        if n_rgb != n:
            raise ValueError(f"rgb has {n_rgb} rows but points has {n}")
    return _set_up(service_pb2.Scene(cloud=cloud), up)


def depth_scene(depth, intrinsics: Intrinsics, up=None):
    """ism.v1.Scene from a depth image: PNG file bytes, or an HxW uint16 array of raw depth units.
    `up` as for cloud_scene(), in the camera's optical frame (x right, y down, z forward)."""
    image = service_pb2.DepthImage(intrinsics=intrinsics.to_proto())
    if isinstance(depth, (bytes, bytearray, memoryview)):
        data = bytes(depth)
        if not data.startswith(PNG_SIGNATURE):
            raise ValueError("depth bytes are not a PNG (raw depth must be an HxW uint16 array)")
        image.encoding = service_pb2.DEPTH_ENCODING_PNG
        image.data = data
    else:
        a = np.asarray(depth)
        if a.ndim != 2 or a.dtype != np.uint16:
            raise ValueError(f"depth array must be HxW uint16, got shape {a.shape} dtype {a.dtype}")
        image.encoding = service_pb2.DEPTH_ENCODING_RAW_UINT16_LE
        image.data = np.ascontiguousarray(a, dtype="<u2").tobytes()
        image.height, image.width = a.shape
    return _set_up(service_pb2.Scene(depth=image), up)


def _pick(table: dict, value, what: str):
    if value is None:
        return 0
    try:
        return table[value.lower()]
    except KeyError:
        raise ValueError(f"unknown {what} {value!r}: one of {', '.join(table)}") from None


def recognition_options(model: str = "", categories: Sequence[str] = (), min_score: Optional[float] = None,
                        max_hypotheses: int = 0, codebook: Optional[str] = None, activation: Optional[str] = None,
                        k: int = 0, cutoff: float = 0.0, weighting: Optional[str] = None,
                        return_keypoints: bool = False, box_selection: Optional[bool] = None,
                        preset: Optional[str] = None, min_confidence: Optional[float] = None,
                        one_answer_per_object: Optional[bool] = None, verify: Optional[bool] = None):
    """ism.v1.RecognitionOptions; strategy names are lower case (codebook 'global'|'separated',
    activation 'knn'|'cutoff', weighting 'categorization'|'localization'|'activation').
    preset 'default' (calibrated confidence, one answer per object) or 'seed' (the seed's
    pipeline); min_confidence (default preset, in [0, 0.99]; the server's default is 0.3); verify
    (default preset: check hypotheses against the scene's depth; the server's default is True). None
    leaves a field to the server's default."""
    options = service_pb2.RecognitionOptions(
        model=model, categories=list(categories), max_hypotheses=max_hypotheses, return_keypoints=return_keypoints,
        strategy=service_pb2.Strategy(codebook=_pick(_CODEBOOKS, codebook, "codebook"),
                                      activation=_pick(_ACTIVATIONS, activation, "activation"), k=k, cutoff=cutoff,
                                      weighting=_pick(_WEIGHTINGS, weighting, "weighting")))
    if min_score is not None:
        options.min_score = min_score
    if box_selection is not None:
        options.box_selection = box_selection
    options.preset = _pick(_PRESETS, preset, "preset")
    if min_confidence is not None:
        options.min_confidence = min_confidence
    if one_answer_per_object is not None:
        options.one_answer_per_object = one_answer_per_object
    if verify is not None:
        options.verify = verify
    return options


def _translate_errors(fn):
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except grpc.RpcError as e:
            raise IsmError(e.code(), e.details() or "") from None

    wrapper.__name__, wrapper.__doc__ = fn.__name__, fn.__doc__
    return wrapper


def _read_pem(path: str, what: str) -> bytes:
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise OSError(f"{what} {path}: {e.strerror or e}") from None
    if b"-----BEGIN " not in data:
        raise ValueError(f"{what} {path}: not a PEM file (no '-----BEGIN' line)")
    return data


def tls_credentials(ca: Optional[str] = None, cert: Optional[str] = None, key: Optional[str] = None):
    """grpc.ChannelCredentials trusting the PEM CA file `ca` (None: the system's CAs), presenting
    the PEM client certificate `cert` with its `key` when given (mTLS). Files are read now, so
    that a missing one is reported here, naming it, rather than as a failed handshake later."""
    if bool(cert) != bool(key):
        raise ValueError("a client certificate needs its key and a key its certificate: give both tls_cert "
                         "and tls_key, or neither")
    return grpc.ssl_channel_credentials(
        root_certificates=_read_pem(ca, "TLS CA") if ca else None,
        private_key=_read_pem(key, "TLS key") if key else None,
        certificate_chain=_read_pem(cert, "TLS certificate") if cert else None)


# Per-call metadata rather than grpc.metadata_call_credentials: gRPC sends call credentials
# only over TLS, and a token over plain text is legitimate on loopback or behind a
# TLS-terminating proxy (ism-client does the same).
def _token_metadata(token: Optional[str]):
    if token is None or token == "":
        return None
    token = token.strip()  # as the server trims its token files: a token read with its newline still works
    if not token or any(ord(c) < 0x21 or ord(c) > 0x7e for c in token):
        raise ValueError("token must be printable ASCII without blanks (it travels as 'authorization: Bearer TOKEN')")
    return (("authorization", f"Bearer {token}"),)


class Client:
    """A connection to ism-server. `address` is any gRPC target: "host:port", or
    "ipv4:10.0.0.1:50051,10.0.0.2:50051" / "dns:///ism-server:50051" with a `service_config`
    that load-balances over several replicas. `timeout` is each call's deadline in seconds.

    Security, as ism-client's flags: `tls=True` trusts the system's CAs; `tls_ca` (a PEM file)
    trusts that CA instead and implies TLS; `tls_cert` + `tls_key` (PEM files) present a client
    certificate to a server that requires one (mTLS); `tls_server_name` is the name the server
    certificate is checked against (default: the host of `address`). `token` is sent with every
    call as the metadata 'authorization: Bearer TOKEN'."""

    def __init__(self, address: str, *, timeout: Optional[float] = 30.0, max_message_mb: int = 64,
                 service_config: Optional[dict] = None, channel_options: Sequence = (), tls: bool = False,
                 tls_ca: Optional[str] = None, tls_cert: Optional[str] = None, tls_key: Optional[str] = None,
                 tls_server_name: Optional[str] = None, token: Optional[str] = None):
        options = [("grpc.max_receive_message_length", max_message_mb << 20),
                   ("grpc.max_send_message_length", max_message_mb << 20), *channel_options]
        if service_config is not None:
            options.append(("grpc.service_config", json.dumps(service_config)))
            # Retries are off unless asked for; a service config with a retryPolicy asks.
            options.append(("grpc.enable_retries", 1))
        self.address = address
        self.timeout = timeout
        self._metadata = _token_metadata(token)
        if tls or tls_ca or tls_cert or tls_key or tls_server_name:
            if tls_server_name:
                options.append(("grpc.ssl_target_name_override", tls_server_name))
            self._channel = grpc.secure_channel(address, tls_credentials(tls_ca, tls_cert, tls_key), options=options)
        else:
            self._channel = grpc.insecure_channel(address, options=options)
        self._stub = service_pb2_grpc.FurnitureRecognizerStub(self._channel)
        self._health = health_pb2_grpc.HealthStub(self._channel)

    def close(self):
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _deadline(self, timeout):
        return self.timeout if timeout is None else timeout

    @_translate_errors
    def recognize(self, scene, options=None, *, request_id: str = "", timeout: Optional[float] = None):
        """Runs one ism.v1.Scene; returns ism.v1.RecognitionResult."""
        request = service_pb2.RecognizeRequest(request_id=request_id, scene=scene,
                                               options=options or service_pb2.RecognitionOptions())
        return self._stub.Recognize(request, timeout=self._deadline(timeout), metadata=self._metadata).result

    def recognize_cloud(self, points, rgb=None, *, width: int = 0, height: int = 0, up=None, request_id: str = "",
                        timeout: Optional[float] = None, **options):
        """Nx3 points in metres (numpy array or lists), optional Nx3 uint8 rgb, `up` as for
        cloud_scene(). `options` are those of recognition_options(). Returns
        ism.v1.RecognitionResult: hypotheses most confident first, with confidence and
        alternatives, and in `gravity` the up the boxes stand along."""
        return self.recognize(cloud_scene(points, rgb, width, height, up), recognition_options(**options),
                              request_id=request_id, timeout=timeout)

    def recognize_depth(self, depth, intrinsics: Intrinsics = KINECT, *, up=None, request_id: str = "",
                        timeout: Optional[float] = None, **options):
        """Depth as PNG bytes or an HxW uint16 array. Returns ism.v1.RecognitionResult."""
        return self.recognize(depth_scene(depth, intrinsics, up), recognition_options(**options),
                              request_id=request_id, timeout=timeout)

    def stream_frames(self, frames: Iterable[Frame], policy: str = "every_frame", *,
                      timeout: Optional[float] = None, **options) -> Iterator:
        """Sends frames as they come from the iterable; yields ism.v1.FrameResult in frame order.
        policy: 'every_frame' (flow control slows the sender) or 'latest_frame_wins' (stale
        frames are dropped and listed in skipped_frame_ids). `timeout` bounds the whole stream
        (default: none, as a live stream may run for hours)."""
        settings = service_pb2.StreamSettings(policy=_pick(_POLICIES, policy, "policy"),
                                              options=recognition_options(**options))

        bad_frame = []  # gRPC consumes requests() on its own thread and only reports CANCELLED

        def requests():
            try:
                for index, frame in enumerate(frames):
                    if frame.depth is not None:
                        scene = depth_scene(frame.depth, frame.intrinsics or KINECT, frame.up)
                    else:
                        scene = cloud_scene(frame.points, frame.rgb, up=frame.up)
                    request = service_pb2.StreamFramesRequest(
                        frame_id=index if frame.frame_id is None else frame.frame_id,
                        timestamp_us=frame.timestamp_us, scene=scene)
                    if index == 0:
                        request.settings.CopyFrom(settings)
                    yield request
            except Exception as e:
                bad_frame.append(e)
                raise

        try:
            yield from self._stub.StreamFrames(requests(), timeout=timeout, metadata=self._metadata)
        except grpc.RpcError as e:
            if bad_frame:
                raise bad_frame[0] from None
            raise IsmError(e.code(), e.details() or "") from None

    @_translate_errors
    def list_models(self, *, timeout: Optional[float] = None):
        """Every loaded model, as a list of ism.v1.ModelInfo."""
        return list(self._stub.ListModels(service_pb2.ListModelsRequest(), timeout=self._deadline(timeout),
                                           metadata=self._metadata).models)

    @_translate_errors
    def get_model(self, name: str, *, timeout: Optional[float] = None):
        return self._stub.GetModel(service_pb2.GetModelRequest(name=name), timeout=self._deadline(timeout),
                                  metadata=self._metadata)

    @_translate_errors
    def health(self, service: str = "", *, timeout: Optional[float] = None) -> str:
        """grpc.health.v1 status of the server ("" = overall): 'SERVING', 'NOT_SERVING', ..."""
        response = self._health.Check(health_pb2.HealthCheckRequest(service=service),
                                      timeout=self._deadline(timeout), metadata=self._metadata)
        return health_pb2.HealthCheckResponse.ServingStatus.Name(response.status)


def connect(address: str, **kwargs) -> Client:
    """Opens a channel (lazily: the first call connects). kwargs as for Client."""
    return Client(address, **kwargs)
