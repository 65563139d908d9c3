"""Python client for the ism-server furniture recognition service (proto/ism/v1/service.proto).

    import ism_client
    with ism_client.connect("127.0.0.1:50051") as client:   # + tls_ca="ca.crt", token=... when secured
        result = client.recognize_cloud(points, up=(0, 0, 1))  # (N, 3) float32 metres; up when known
        for h in result.hypotheses:                      # most confident first, one per object
            print(h.category, h.confidence, h.center, [(a.category, a.confidence) for a in h.alternatives])
        print(result.gravity.up, result.gravity.source)  # the up the boxes stand along
"""
from .client import (KINECT, Client, Frame, IsmError, Intrinsics, cloud_scene, connect, depth_scene,
                     recognition_options, tls_credentials)
from .pcd import Cloud, read_pcd
from ._stubs import model_pb2, service_pb2

__all__ = ["KINECT", "Client", "Cloud", "Frame", "IsmError", "Intrinsics", "cloud_scene", "connect", "depth_scene",
           "model_pb2", "read_pcd", "recognition_options", "service_pb2", "tls_credentials"]
