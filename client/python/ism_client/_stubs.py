"""Finds the Python stubs that the build generates from proto/ (they are not committed, so that
they can never drift from the contract). The build writes them to BUILD/client/python/gen;
ISM_PY_STUBS names that folder, or the stubs may already be importable (installed on sys.path).
"""
import importlib
import os
import sys

_ENV = "ISM_PY_STUBS"


def _import_all():
    return (
        importlib.import_module("ism.v1.model_pb2"),
        importlib.import_module("ism.v1.service_pb2"),
        importlib.import_module("ism.v1.service_pb2_grpc"),
        importlib.import_module("grpc.health.v1.health_pb2"),
        importlib.import_module("grpc.health.v1.health_pb2_grpc"),
    )


def load():
    stub_dir = os.environ.get(_ENV)
    if stub_dir:
        if not os.path.isfile(os.path.join(stub_dir, "ism", "v1", "service_pb2.py")):
            raise ImportError(f"{_ENV}={stub_dir} holds no ism/v1/service_pb2.py: build the target "
                              "ism_client_python_stubs and point it at BUILD/client/python/gen")
        if stub_dir not in sys.path:
            sys.path.insert(0, stub_dir)
    # The stubs' "grpc.health.v1" lives beside grpcio's own "grpc" package, so "grpc" must
    # span both folders; grpcio's __init__ does not declare a namespace, so extend it here.
    import grpc

    if stub_dir:
        extra = os.path.join(stub_dir, "grpc")
        if extra not in grpc.__path__:
            grpc.__path__.append(extra)
    try:
        return _import_all()
    except ImportError as e:
        raise ImportError(f"ism_client cannot import its generated stubs ({e}); set {_ENV} to "
                          "BUILD/client/python/gen after building target ism_client_python_stubs") from e


model_pb2, service_pb2, service_pb2_grpc, health_pb2, health_pb2_grpc = load()
