"""Builds deploy/Containerfile with podman, runs the image as deploy/compose.yaml and the
Kubernetes Deployment do (non-root, read-only root filesystem) and calls it from the C++
ism-client on 127.0.0.1: health, one recognition, the image's own HEALTHCHECK, and a clean
SIGTERM drain. It also measures what the image adds to its base, which a fleet pulls onto every
robot: at most MAX_ABOVE_BASE_MB. ctest labels it `container`.

The image's compile stage is the tree's own ism-server by default (`--build-context build=DIR`
stands in for the stage named build, as under BuildKit): the main build has compiled the same
sources against the same Debian 12 packages, and compiling them again inside the image took 12
minutes of a fresh machine's CI. What only the image can get wrong is still checked: the
toolchain stage is built and configures the project from its --build package list alone.
ISM_CONTAINER_COMPILE=1 builds the whole Containerfile instead, as a Docker user does.

Three adjustments for this CI sandbox, none of which the image needs (see
../shared/docs/CONTAINERS.md when present): the base image is made locally with debootstrap
(base_image.sh, no registry here), the build uses --isolation=chroot, and the container runs
through runc-no-nproc (the sandbox refuses RLIMIT_NPROC) with --network=host."""
import json
import os
import subprocess
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "clients"))
import scenes  # noqa: E402
from server_process import free_port  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.environ.get("ISM_SOURCE_DIR", os.path.join(HERE, "..", ".."))
CLIENT = os.environ.get("ISM_CLIENT_BIN", "")
SERVER = os.environ.get("ISM_SERVER_BIN", "")
COMPILE = os.environ.get("ISM_CONTAINER_COMPILE", "") == "1"
MODEL_DIR = os.environ.get("ISM_TEST_MODEL_DIR", "")
# A tag of its own per run, so that two checkouts testing on one machine never run each other's
# image; removed afterwards (the layers stay cached for the next build).
IMAGE = f"localhost/ism-server:test-{os.getpid()}"
BASE = "docker.io/library/debian:bookworm-slim"
# Issue 18's budget for the layers above debian:bookworm-slim, uncompressed.
MAX_ABOVE_BASE_MB = 120
PODMAN_RUN = ["podman", "--runtime", os.path.join(HERE, "runc-no-nproc")]


def run(cmd, timeout, **kwargs):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kwargs)


class ContainerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not CLIENT or not SERVER or not MODEL_DIR:
            raise RuntimeError("ISM_CLIENT_BIN, ISM_SERVER_BIN and ISM_TEST_MODEL_DIR must be set (ctest sets them)")
        base = run(["bash", os.path.join(HERE, "base_image.sh")], timeout=900)
        if base.returncode:
            raise RuntimeError(f"cannot make the base image:\n{base.stdout}{base.stderr}")
        start = time.monotonic()
        # --format docker keeps the HEALTHCHECK, which the OCI image format has no field for.
        podman_build = ["podman", "build", "--pull=never", "--isolation=chroot", "--format", "docker",
                        "-f", "deploy/Containerfile", "--ignorefile", "deploy/Containerfile.dockerignore"]
        if COMPILE:
            build = run(podman_build + ["-t", IMAGE, "."], timeout=3600, cwd=SOURCE)
        else:
            cls.configure_in_toolchain(podman_build)
            with tempfile.TemporaryDirectory() as stage:
                binary = os.path.join(stage, "opt", "ism", "bin", "ism-server")
                os.makedirs(os.path.dirname(binary))
                # Stripped, as the build stage installs it.
                subprocess.run(["strip", "-o", binary, SERVER], check=True, timeout=120)
                build = run(podman_build + ["--build-context", f"build={stage}", "-t", IMAGE, "."],
                            timeout=1800, cwd=SOURCE)
        cls.build_seconds = time.monotonic() - start
        if build.returncode:
            raise RuntimeError(f"podman build failed:\n{build.stdout[-6000:]}{build.stderr[-6000:]}")
        inspect = run(["podman", "image", "inspect", "--format", "{{.Size}} {{.Config.User}}", IMAGE], timeout=60)
        size, cls.user = inspect.stdout.split()
        base_size = run(["podman", "image", "inspect", "--format", "{{.Size}}", BASE], timeout=60).stdout
        cls.size_mb, cls.above_base_mb = int(size) / 1e6, (int(size) - int(base_size)) / 1e6
        print(f"image {IMAGE}: {cls.size_mb:.0f} MB, {cls.above_base_mb:.1f} MB above {BASE}, "
              f"built in {cls.build_seconds:.0f} s", flush=True)

        cls.port, cls.metrics_port = free_port(), free_port()
        cls.name = f"ism-container-test-{os.getpid()}"
        # The model is mounted the way deploy/compose.yaml documents custom models. --read-only
        # without podman's default tmpfs on /tmp, /var/tmp and /run: nothing in the container is
        # writable, as under Docker's --read-only and Kubernetes' readOnlyRootFilesystem.
        started = run(PODMAN_RUN + ["run", "-d", "--name", cls.name, "--read-only", "--read-only-tmpfs=false",
                                    "--network=host", "--ulimit", "nofile=20000:20000",
                                    "-v", f"{os.path.abspath(MODEL_DIR)}:/models:ro", "-e", "ISM_MODELS=/models",
                                    "-e", f"ISM_LISTEN=127.0.0.1:{cls.port}",
                                    "-e", f"ISM_METRICS_LISTEN=127.0.0.1:{cls.metrics_port}", "-e", "ISM_THREADS=2",
                                    IMAGE], timeout=120)
        if started.returncode:
            raise RuntimeError(f"podman run failed:\n{started.stdout}{started.stderr}")
        cls.address = f"127.0.0.1:{cls.port}"
        deadline = time.monotonic() + 60
        while run([CLIENT, "--server", cls.address, "--deadline-ms", "2000", "health"], timeout=30).returncode:
            if time.monotonic() > deadline:
                raise RuntimeError(f"the container never became healthy:\n{cls.logs()}")
            time.sleep(0.5)
        cls.ready_seconds = time.monotonic() - start - cls.build_seconds

    @classmethod
    def configure_in_toolchain(cls, podman_build):
        """The Containerfile's toolchain stage, and CMake's configure of ism-server in it over the
        source tree (mounted read-only): a package the build needs but install-deps.sh --build
        leaves out fails here."""
        # By its image ID, untagged: removing a tag would remove the layers under it too, and the
        # next run would install the toolchain again (four minutes).
        with tempfile.TemporaryDirectory() as tmp:
            iidfile = os.path.join(tmp, "toolchain.iid")
            toolchain = run(podman_build + ["--target", "toolchain", "--iidfile", iidfile, "."], timeout=1800, cwd=SOURCE)
            if toolchain.returncode:
                raise RuntimeError(f"the toolchain stage failed:\n{toolchain.stdout[-6000:]}{toolchain.stderr[-6000:]}")
            with open(iidfile) as f:
                image_id = f.read().strip()
        configure = run(PODMAN_RUN + ["run", "--rm", "--network=host", "--ulimit", "nofile=20000:20000",
                                      "-v", f"{os.path.abspath(SOURCE)}:/src:ro", image_id,
                                      "cmake", "-S", "/src", "-B", "/tmp/configure", "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                                      "-DISM_BUILD_TESTS=OFF", "-DISM_BUILD_SERVICE=ON"], timeout=600)
        if configure.returncode:
            raise RuntimeError("ism-server does not configure in the toolchain stage (deploy/install-deps.sh "
                               f"--build):\n{configure.stdout[-6000:]}{configure.stderr[-6000:]}")

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "name", None):
            run(PODMAN_RUN + ["rm", "-f", "-t", "0", cls.name], timeout=120)
        run(["podman", "rmi", "--ignore", "--no-prune", IMAGE], timeout=120)

    @classmethod
    def logs(cls):
        result = run(["podman", "logs", cls.name], timeout=60)
        return result.stdout + result.stderr

    def test_0_layers_above_the_base_fit_the_budget(self):
        self.assertLessEqual(self.above_base_mb, MAX_ABOVE_BASE_MB,
                             "the runtime stage grew: see deploy/install-deps.sh --runtime and deploy/Containerfile")

    def test_1_image_runs_as_non_root(self):
        self.assertEqual(self.user, "10001")
        uid = run(PODMAN_RUN + ["exec", self.name, "id", "-u"], timeout=60)
        self.assertEqual(uid.stdout.strip(), "10001", uid.stderr)
        # The server itself (PID 1), real and effective uid alike.
        status = run(PODMAN_RUN + ["exec", self.name, "cat", "/proc/1/status"], timeout=60)
        uids = next(line.split()[1:] for line in status.stdout.splitlines() if line.startswith("Uid:"))
        self.assertEqual(set(uids), {"10001"}, status.stdout + status.stderr)

    def test_2_root_filesystem_is_read_only(self):
        inspect = run(["podman", "inspect", "--format", "{{.HostConfig.ReadonlyRootfs}}", self.name], timeout=60)
        self.assertEqual(inspect.stdout.strip(), "true", inspect.stderr)
        for path in ("/opt/ism/written-by-test", "/tmp/written-by-test"):
            with self.subTest(path=path):
                write = run(PODMAN_RUN + ["exec", self.name, "sh", "-c", f": > {path}"], timeout=60)
                self.assertNotEqual(write.returncode, 0, f"{path} is writable")
                self.assertIn("Read-only file system", write.stderr)

    def test_3_health_and_recognition_from_the_cpp_client(self):
        health = run([CLIENT, "--server", self.address, "health"], timeout=60)
        self.assertEqual(health.returncode, 0, health.stdout + health.stderr)
        self.assertIn("SERVING", health.stdout)
        with tempfile.TemporaryDirectory() as tmp:
            pcd = os.path.join(tmp, "scene.pcd")
            scenes.write_pcd(pcd, scenes.box_on_floor(), kind="binary")
            start = time.monotonic()
            recognized = run([CLIENT, "--server", self.address, "--json", "recognize", pcd], timeout=120)
            print(f"recognition through the container: {time.monotonic() - start:.2f} s", flush=True)
        self.assertEqual(recognized.returncode, 0, recognized.stdout + recognized.stderr + self.logs())
        result = json.loads(recognized.stdout.splitlines()[0])["response"]["result"]
        self.assertEqual(int(result["input_points"]), len(scenes.box_on_floor()))
        served_from = {os.path.splitext(f)[0] for f in os.listdir(MODEL_DIR) if f.endswith(".ismm")}
        self.assertIn(result["model_name"], served_from)

    def test_4_healthcheck_command_of_the_image_passes(self):
        check = run(PODMAN_RUN + ["healthcheck", "run", self.name], timeout=60)
        self.assertEqual(check.returncode, 0, check.stdout + check.stderr)

    def test_5_sigterm_drains_and_exits_cleanly(self):
        stopped = run(PODMAN_RUN + ["stop", "-t", "30", self.name], timeout=120)
        self.assertEqual(stopped.returncode, 0, stopped.stderr)
        code = run(["podman", "inspect", "--format", "{{.State.ExitCode}}", self.name], timeout=60)
        self.assertEqual(code.stdout.strip(), "0", self.logs())
        self.assertIn("draining", self.logs())
        print(f"build {self.build_seconds:.0f} s, start to SERVING {self.ready_seconds:.1f} s", flush=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
