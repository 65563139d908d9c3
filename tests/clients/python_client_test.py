"""The Python client (client/python) against a real ism-server on 127.0.0.1.

Run by ctest (tests/clients/CMakeLists.txt), which sets ISM_SERVER_BIN, ISM_TEST_MODEL_DIR,
ISM_PY_STUBS and PYTHONPATH. The security tests make their certificates with openssl."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import certs  # noqa: E402
import ism_client  # noqa: E402
import scenes  # noqa: E402
from server_process import ServerProcess  # noqa: E402
from ism_client.pcd import lzf_decompress, read_pcd  # noqa: E402

SMALL = ism_client.Intrinsics(**scenes.SMALL_CAMERA)


class PcdReaderTest(unittest.TestCase):
    """The reader the command line uses for .pcd files; no server needed."""

    def test_every_data_kind_round_trips_points_and_colours(self):
        points = scenes.box_on_floor(step=0.1)
        rgb = np.random.default_rng(1).integers(0, 256, points.shape).astype(np.uint8)
        with tempfile.TemporaryDirectory() as tmp:
            for kind in ("ascii", "binary", "binary_compressed"):
                with self.subTest(kind=kind):
                    path = os.path.join(tmp, f"{kind}.pcd")
                    scenes.write_pcd(path, points, rgb, kind)
                    cloud = read_pcd(path)
                    np.testing.assert_allclose(cloud.points, points, rtol=0, atol=1e-6)
                    np.testing.assert_array_equal(cloud.rgb, rgb)
                    self.assertEqual((cloud.width, cloud.height), (0, 0))

    def test_lzf_back_reference_may_overlap_its_own_output(self):
        # literal "ab", then copy 4 bytes from 2 back: "ab" + "abab"
        self.assertEqual(lzf_decompress(b"\x01ab" + bytes([(4 - 2) << 5, 1]), 6), b"ababab")
        with self.assertRaisesRegex(ValueError, "header says 7"):
            lzf_decompress(b"\x01ab" + bytes([(4 - 2) << 5, 1]), 7)

    def test_truncated_and_foreign_files_are_rejected_with_their_path(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "cut.pcd")
            scenes.write_pcd(path, scenes.box_on_floor(step=0.1), kind="binary")
            with open(path, "r+b") as f:
                f.truncate(os.path.getsize(path) - 5)
            with self.assertRaisesRegex(ValueError, "cut.pcd: truncated"):
                read_pcd(path)
            other = os.path.join(tmp, "other.pcd")
            with open(other, "wb") as f:
                f.write(b"ply\nformat ascii 1.0\n")
            with self.assertRaisesRegex(ValueError, "other.pcd: not a PCD"):
                read_pcd(other)


class CommandLineOutputTest(unittest.TestCase):
    """What the command line prints of an answer; no server needed."""

    def test_gravity_line_says_where_up_came_from_as_ism_client_does(self):
        from ism_client.__main__ import gravity_line
        pb = ism_client.service_pb2
        g = pb.Gravity(up=pb.Vec3(z=1), source=pb.UP_SOURCE_FLOOR, floor_level=-1.25, floor_points=512, walls=2,
                       wall_points=90)
        self.assertEqual(gravity_line(g), "up: (0.00, 0.00, 1.00) floor, floor at -1.25 m (512 points), 2 walls (90 points)")
        g.ClearField("floor_level")
        g.source, g.walls = pb.UP_SOURCE_GIVEN, 0
        self.assertEqual(gravity_line(g), "up: (0.00, 0.00, 1.00) given, no floor found")


class ClientAgainstServerTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = ServerProcess().start()
        cls.client = ism_client.connect(cls.server.address, timeout=60)
        cls.models = cls.client.list_models()
        if not cls.models:
            raise RuntimeError(f"the server loaded no model from {cls.server.model_dir}:\n{cls.server.log()}")
        cls.model = cls.models[0]
        cls.points = scenes.box_on_floor()

    @classmethod
    def tearDownClass(cls):
        cls.client.close()
        cls.server.stop()

    def assert_valid_result(self, result, input_points=None):
        self.assertEqual(result.model_name, self.model.name)
        self.assertEqual(result.model_version, self.model.version)
        if input_points is not None:
            self.assertEqual(result.input_points, input_points)
        self.assertGreater(result.surface_points, 0)
        self.assertGreater(result.total_ms, 0)
        self.assertTrue(result.timings, "the server reports per-stage timings")
        categories = {c.name for c in self.model.categories}
        for h in result.hypotheses:
            self.assertIn(h.category, categories)
            self.assertGreaterEqual(h.score, h.threshold)

    def test_health_is_serving(self):
        self.assertEqual(self.client.health(), "SERVING")

    def test_list_and_get_model_agree(self):
        info = self.client.get_model(self.model.name)
        self.assertEqual(info.version, self.model.version)
        self.assertEqual([c.name for c in info.categories], [c.name for c in self.model.categories])
        self.assertGreater(len(info.categories), 0)
        with self.assertRaises(ism_client.IsmError) as caught:
            self.client.get_model("no-such-model")
        self.assertEqual(caught.exception.code.name, "NOT_FOUND")

    def test_recognize_cloud_from_numpy_and_from_lists(self):
        result = self.client.recognize_cloud(self.points, request_id="py-numpy")
        self.assert_valid_result(result, input_points=len(self.points))
        few = self.points[::4]
        with_colour = self.client.recognize_cloud(few.tolist(), rgb=np.full(few.shape, 200, np.uint8))
        self.assert_valid_result(with_colour, input_points=len(few))

    def test_recognize_depth_raw_and_png_give_the_same_result(self):
        depth = scenes.depth_of_box()
        raw = self.client.recognize_depth(depth, SMALL)
        png = self.client.recognize_depth(scenes.png16(depth), SMALL)
        self.assert_valid_result(raw)
        self.assertEqual(raw.input_points, int(np.count_nonzero(depth)))
        self.assertEqual((png.input_points, png.keypoints, len(png.hypotheses)),
                         (raw.input_points, raw.keypoints, len(raw.hypotheses)))

    def test_server_errors_carry_their_grpc_code(self):
        with self.assertRaises(ism_client.IsmError) as caught:
            self.client.recognize_cloud(self.points, model="no-such-model")
        self.assertEqual(caught.exception.code.name, "NOT_FOUND")
        with self.assertRaises(ism_client.IsmError) as caught:
            self.client.recognize_depth(scenes.depth_of_box(), ism_client.Intrinsics(0, 0, 0, 0))
        self.assertEqual(caught.exception.code.name, "INVALID_ARGUMENT")
        self.assertIn("fx", caught.exception.message)

    def test_bad_input_is_refused_before_sending(self):
        with self.assertRaisesRegex(ValueError, r"shape \(N, 3\)"):
            self.client.recognize_cloud(np.zeros((10, 2)))
        with self.assertRaisesRegex(ValueError, "HxW uint16"):
            self.client.recognize_depth(np.zeros((4, 4), np.float32), SMALL)
        with self.assertRaisesRegex(ValueError, "unknown activation"):
            self.client.recognize_cloud(self.points, activation="nearest")
        with self.assertRaisesRegex(ValueError, "unknown preset"):
            self.client.recognize_cloud(self.points, preset="fancy")
        with self.assertRaisesRegex(ValueError, r"up must be three numbers"):
            self.client.recognize_cloud(self.points, up=(0, 1))

    def test_default_preset_confidences_and_the_given_up(self):
        result = self.client.recognize_cloud(self.points, up=(0, 0, 2), min_confidence=0.01)
        self.assert_valid_result(result, input_points=len(self.points))
        for i, h in enumerate(result.hypotheses):
            self.assertTrue(0.01 <= h.confidence <= 1, h.confidence)
            if i:
                self.assertLessEqual(h.confidence, result.hypotheses[i - 1].confidence, "not most confident first")
            for a in h.alternatives:
                self.assertNotEqual(a.category, h.category)
                self.assertLessEqual(a.confidence, h.confidence)
        # A model trained before the gravity stage (no front-end gravity parameters) reports none.
        if self.model.front_end.HasField("gravity"):
            self.assertEqual(result.gravity.source, ism_client.service_pb2.UP_SOURCE_GIVEN)
            self.assertEqual((result.gravity.up.x, result.gravity.up.y, result.gravity.up.z), (0, 0, 1))
        else:
            self.assertFalse(result.HasField("gravity"))

    def test_seed_preset_ranks_by_score_over_threshold_and_merges_nothing(self):
        result = self.client.recognize_cloud(self.points, preset="seed", min_score=0, box_selection=False,
                                             max_hypotheses=6)
        self.assertTrue(result.hypotheses)
        relative = [h.score / h.threshold if h.threshold > 0 else h.score for h in result.hypotheses]
        self.assertEqual(relative, sorted(relative, reverse=True))
        self.assertEqual([len(h.alternatives) for h in result.hypotheses], [0] * len(result.hypotheses))

    def test_bad_up_and_min_confidence_are_invalid_arguments_naming_the_field(self):
        for options, field in ((dict(up=(0, 0, 0)), "scene.up = (0, 0, 0)"), (dict(up=(float("inf"), 0, 1)), "scene.up"),
                               (dict(min_confidence=1.5), "options.min_confidence = 1.5"),
                               (dict(min_confidence=-1), "options.min_confidence = -1")):
            with self.subTest(**options):
                with self.assertRaises(ism_client.IsmError) as caught:
                    self.client.recognize_cloud(self.points, **options)
                self.assertEqual(caught.exception.code.name, "INVALID_ARGUMENT")
                self.assertIn(field, caught.exception.message)
        frames = [ism_client.Frame(points=self.points, up=(0, 0, 0)), ism_client.Frame(points=self.points, up=(0, 0, 1))]
        results = list(self.client.stream_frames(frames))
        self.assertEqual([r.WhichOneof("outcome") for r in results], ["error", "result"])
        self.assertIn("scene.up", results[0].error.message)

    def test_stream_answers_every_frame_in_order_and_isolates_a_bad_one(self):
        cloud = self.points[::2]
        frames = [ism_client.Frame(points=cloud, timestamp_us=1000),
                  ism_client.Frame(depth=scenes.depth_of_box(), intrinsics=ism_client.Intrinsics(0, 0, 0, 0)),
                  ism_client.Frame(depth=scenes.png16(scenes.depth_of_box()), intrinsics=SMALL, frame_id=42)]
        results = list(self.client.stream_frames(frames, policy="every_frame"))
        self.assertEqual([r.frame_id for r in results], [0, 1, 42])
        self.assertEqual([r.WhichOneof("outcome") for r in results], ["result", "error", "result"])
        self.assertEqual(results[0].timestamp_us, 1000)
        self.assert_valid_result(results[0].result, input_points=len(cloud))
        self.assertEqual(results[1].error.code, 3)  # INVALID_ARGUMENT
        with self.assertRaisesRegex(ValueError, "unknown policy"):
            list(self.client.stream_frames(frames, policy="fastest"))
        with self.assertRaisesRegex(ValueError, r"shape \(N, 3\)"):  # raised on gRPC's sending thread
            list(self.client.stream_frames([frames[0], ism_client.Frame(points=np.zeros((5, 4)))]))

    def run_cli(self, *args):
        env = dict(os.environ, ISM_SERVER=self.server.address)
        return subprocess.run([sys.executable, "-m", "ism_client", *args], env=env, capture_output=True,
                              text=True, timeout=120)

    def test_command_line(self):
        health = self.run_cli("health")
        self.assertEqual((health.returncode, health.stdout.strip()), (0, "SERVING"), health.stderr)
        models = self.run_cli("models")
        self.assertEqual(models.returncode, 0, models.stderr)
        self.assertIn(f"{self.model.name}@{self.model.version}", models.stdout)
        with tempfile.TemporaryDirectory() as tmp:
            pcd = os.path.join(tmp, "scene.pcd")
            scenes.write_pcd(pcd, self.points, kind="binary_compressed")
            cloud = self.run_cli("recognize", pcd)
            self.assertEqual(cloud.returncode, 0, cloud.stderr)
            self.assertIn(f"model {self.model.name}@{self.model.version}: {len(self.points)} points", cloud.stdout)
            chosen = self.run_cli("recognize", pcd, "--preset", "seed", "--min-score", "0", "--up", "0,0,1")
            self.assertEqual(chosen.returncode, 0, chosen.stderr)
            self.assertRegex(chosen.stdout, r"\n  \w+ +confidence [01]\.\d{3}  score")
            if self.model.front_end.HasField("gravity"):
                self.assertIn("up: (0.00, 0.00, 1.00) given", chosen.stdout)
            for bad in (("--up", "0,0"), ("--preset", "fancy"), ("--min-confidence", "x")):
                refused = self.run_cli("recognize", pcd, *bad)
                self.assertEqual(refused.returncode, 2, refused.stderr)
                self.assertIn(bad[0], refused.stderr)
            far = self.run_cli("recognize", pcd, "--min-confidence", "1")
            self.assertEqual(far.returncode, 1, far.stderr)
            self.assertIn("options.min_confidence = 1 ", far.stderr)
            png = os.path.join(tmp, "depth.png")
            with open(png, "wb") as f:
                f.write(scenes.png16(scenes.depth_of_box()))
            small = [f"--{k.replace('_', '-')}={v}" for k, v in scenes.SMALL_CAMERA.items()]
            depth = self.run_cli("--json", "recognize", png, *small)
            self.assertEqual(depth.returncode, 0, depth.stderr)
            self.assertEqual(int(json.loads(depth.stdout)["input_points"]),
                             int(np.count_nonzero(scenes.depth_of_box())))
            missing = self.run_cli("recognize", os.path.join(tmp, "missing.pcd"))
            self.assertEqual(missing.returncode, 2)
            self.assertIn("missing.pcd", missing.stderr)
        unknown = self.run_cli("models", "no-such-model")
        self.assertEqual(unknown.returncode, 1)
        self.assertIn("NOT_FOUND", unknown.stderr)


class SecuredServerTest(unittest.TestCase):
    """TLS, mTLS and bearer tokens against servers started with ism-server's security flags."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.pki = certs.Pki(cls.tmp.name)
        cls.server = ServerProcess(extra_args=cls.pki.server_flags()).start()
        cls.points = scenes.box_on_floor()[::4]

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        cls.tmp.cleanup()

    def connect(self, server=None, **kwargs):
        client = ism_client.connect((server or self.server).address, timeout=30, **kwargs)
        self.addCleanup(client.close)
        return client

    def assert_fails(self, code: str, call, *args, message=""):
        with self.assertRaises(ism_client.IsmError) as caught:
            call(*args)
        self.assertEqual(caught.exception.code.name, code, caught.exception.message)
        self.assertIn(message, caught.exception.message)
        return caught.exception

    def test_no_token_is_unauthenticated_and_health_stays_open(self):
        client = self.connect(tls_ca=self.pki.path("ca.crt"))
        self.assertEqual(client.health(), "SERVING")
        self.assert_fails("UNAUTHENTICATED", client.recognize_cloud, self.points, message="authorization: Bearer")
        self.assert_fails("UNAUTHENTICATED", client.list_models)
        with self.assertRaises(ism_client.IsmError) as caught:
            list(client.stream_frames([ism_client.Frame(points=self.points)]))
        self.assertEqual(caught.exception.code.name, "UNAUTHENTICATED")

    def test_wrong_token_is_unauthenticated(self):
        client = self.connect(tls_ca=self.pki.path("ca.crt"), token="not-a-token-of-this-server")
        self.assert_fails("UNAUTHENTICATED", client.list_models, message="not accepted")

    def test_right_token_gets_results_on_every_rpc(self):
        for token in (certs.USER_TOKEN, certs.ADMIN_TOKEN + "\n"):  # a token read from a file keeps its newline
            with self.subTest(token=token.strip()[:5]):
                client = self.connect(tls_ca=self.pki.path("ca.crt"), token=token)
                models = client.list_models()
                self.assertTrue(models, self.server.log())
                self.assertEqual(client.get_model(models[0].name).name, models[0].name)
                result = client.recognize_cloud(self.points)
                self.assertEqual(result.input_points, len(self.points))
                self.assertEqual(result.model_name, models[0].name)
                frames = list(client.stream_frames([ism_client.Frame(points=self.points, frame_id=7)]))
                self.assertEqual([(r.frame_id, r.WhichOneof("outcome")) for r in frames], [(7, "result")])

    def test_wrong_ca_fails_the_handshake(self):
        client = self.connect(tls_ca=self.pki.path("rogue-ca.crt"), token=certs.USER_TOKEN)
        for call in (client.health, client.list_models):
            with self.subTest(call=call.__name__):
                self.assert_fails("UNAVAILABLE", call, message="certificate verify failed")

    def test_plain_text_to_a_tls_server_fails(self):
        self.assert_fails("UNAVAILABLE", self.connect(token=certs.USER_TOKEN).health)

    def test_server_name_is_checked_and_can_be_overridden(self):
        with ServerProcess(extra_args=self.pki.server_flags("named-server")) as named:
            # The certificate names only "ism-server", not the 127.0.0.1 dialled.
            self.assert_fails("UNAVAILABLE", self.connect(named, tls_ca=self.pki.path("ca.crt")).health)
            client = self.connect(named, tls_ca=self.pki.path("ca.crt"), tls_server_name="ism-server",
                                  token=certs.USER_TOKEN)
            self.assertEqual(client.health(), "SERVING")
            self.assertTrue(client.list_models())

    def test_mutual_tls_needs_a_client_certificate_from_the_client_ca(self):
        with ServerProcess(extra_args=self.pki.server_flags(client_ca="ca")) as mtls:
            ca = self.pki.path("ca.crt")
            accepted = self.connect(mtls, tls_ca=ca, tls_cert=self.pki.path("client.crt"),
                                    tls_key=self.pki.path("client.key"), token=certs.USER_TOKEN)
            self.assertTrue(accepted.list_models())
            self.assert_fails("UNAVAILABLE", self.connect(mtls, tls_ca=ca, token=certs.USER_TOKEN).health)
            rogue = self.connect(mtls, tls_ca=ca, tls_cert=self.pki.path("rogue-client.crt"),
                                 tls_key=self.pki.path("rogue-client.key"), token=certs.USER_TOKEN)
            self.assert_fails("UNAVAILABLE", rogue.health)

    def test_bad_security_options_are_refused_before_connecting(self):
        with self.assertRaisesRegex(ValueError, "give both tls_cert and tls_key"):
            ism_client.connect(self.server.address, tls_cert=self.pki.path("client.crt"))
        with self.assertRaisesRegex(OSError, "TLS CA .*missing.crt"):
            ism_client.connect(self.server.address, tls_ca=self.pki.path("missing.crt"))
        with self.assertRaisesRegex(ValueError, "tokens: not a PEM file"):
            ism_client.connect(self.server.address, tls_ca=self.pki.path("tokens"))
        with self.assertRaisesRegex(ValueError, "printable ASCII"):
            ism_client.connect(self.server.address, token="two words")

    def run_cli(self, *args, **env):
        return subprocess.run([sys.executable, "-m", "ism_client", "--server", self.server.address, *args],
                              env=dict(os.environ, **env), capture_output=True, text=True, timeout=120)

    def test_command_line_takes_the_ca_and_the_token_from_flags_or_environment(self):
        ca = self.pki.path("ca.crt")
        models = self.run_cli("--tls-ca", ca, "models", ISM_TOKEN=certs.USER_TOKEN)
        self.assertEqual(models.returncode, 0, models.stderr)
        self.assertIn("@", models.stdout)
        by_flag = self.run_cli("--token", certs.USER_TOKEN, "models", ISM_TLS_CA=ca)
        self.assertEqual((by_flag.returncode, by_flag.stdout), (0, models.stdout), by_flag.stderr)
        without = self.run_cli("--tls-ca", ca, "models")
        self.assertEqual(without.returncode, 1)
        self.assertIn("UNAUTHENTICATED", without.stderr)
        rogue = self.run_cli("--tls-ca", self.pki.path("rogue-ca.crt"), "models", ISM_TOKEN=certs.USER_TOKEN)
        self.assertEqual(rogue.returncode, 1)
        self.assertIn("UNAVAILABLE", rogue.stderr)
        half = self.run_cli("--tls-ca", ca, "--tls-cert", self.pki.path("client.crt"), "health")
        self.assertEqual(half.returncode, 2)
        self.assertIn("--tls-key", half.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
