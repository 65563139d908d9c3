"""Scale-out: three ism-server replicas on 127.0.0.1 behind client-side round-robin load
balancing (what deploy/k8s/service.yaml's headless Service gives clients in a cluster).
Every replica must serve requests, and when one is SIGKILLed mid-run the client's retry policy
must carry every request to the survivors."""
import concurrent.futures
import os
import sys
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "clients"))
import ism_client  # noqa: E402
import scenes  # noqa: E402
from server_process import ServerProcess  # noqa: E402

SERVICE_CONFIG = {
    "loadBalancingConfig": [{"round_robin": {}}],
    "methodConfig": [{
        "name": [{"service": "ism.v1.FurnitureRecognizer"}],
        # A call that reached a replica which then died fails UNAVAILABLE before any response
        # header arrived, so gRPC may replay it on another replica.
        "retryPolicy": {"maxAttempts": 4, "initialBackoff": "0.05s", "maxBackoff": "0.5s",
                        "backoffMultiplier": 2, "retryableStatusCodes": ["UNAVAILABLE"]},
    }],
}
REQUESTS_BEFORE = 12
REQUESTS_DURING = 30
KILL_AFTER = 6  # completed requests of the second phase before one replica is killed


class ScaleOutTest(unittest.TestCase):
    def setUp(self):
        self.replicas = []
        for _ in range(3):
            self.replicas.append(ServerProcess(threads=1).start())
            self.addCleanup(self.replicas[-1].stop)
        target = "ipv4:" + ",".join(r.address for r in self.replicas)
        self.client = ism_client.connect(target, timeout=60, service_config=SERVICE_CONFIG)
        self.addCleanup(self.client.close)
        self.points = scenes.box_on_floor(step=0.04)

    @staticmethod
    def served(replicas, at_least: int):
        """Recognize calls counted by each replica's /metrics. A replica counts a call just after
        answering it, so wait (briefly) until the counts add up to what the client saw."""
        deadline = time.monotonic() + 5
        while True:
            counts = [r.requests_served("Recognize") for r in replicas]
            if sum(counts) >= at_least or time.monotonic() > deadline:
                return counts
            time.sleep(0.05)

    def test_round_robin_spreads_load_and_survives_a_killed_replica(self):
        start = time.monotonic()
        for i in range(REQUESTS_BEFORE):
            result = self.client.recognize_cloud(self.points, request_id=f"before-{i}")
            self.assertEqual(result.input_points, len(self.points))
        before = self.served(self.replicas, REQUESTS_BEFORE)
        print(f"Recognize calls per replica before the kill: {before}")
        self.assertEqual(sum(before), REQUESTS_BEFORE)
        self.assertTrue(all(n >= 1 for n in before), f"a replica served nothing: {before}")

        victim, survivors = self.replicas[1], [self.replicas[0], self.replicas[2]]
        survivors_before = [before[0], before[2]]
        outcomes = []
        with concurrent.futures.ThreadPoolExecutor(max_workers=3) as pool:
            futures = [pool.submit(self.client.recognize_cloud, self.points, request_id=f"during-{i}")
                       for i in range(REQUESTS_DURING)]
            done = 0
            for future in concurrent.futures.as_completed(futures):
                outcomes.append(future.exception())
                done += 1
                if done == KILL_AFTER:
                    victim.kill()
                    killed_at = done
        failures = [e for e in outcomes if e is not None]
        self.assertFalse(failures, f"{len(failures)} of {REQUESTS_DURING} calls failed: {failures[:3]}")
        after = self.served(survivors, sum(survivors_before) + REQUESTS_DURING - killed_at)
        gained = [a - b for a, b in zip(after, survivors_before)]
        print(f"killed replica {victim.address} after {killed_at} completed calls; survivors served "
              f"{gained} of the {REQUESTS_DURING} calls of the second phase; all succeeded; "
              f"{time.monotonic() - start:.1f} s in all")
        # The victim answered some calls before it died; every call it did not answer was
        # served by a survivor, and both survivors took part.
        self.assertGreaterEqual(sum(gained), REQUESTS_DURING - killed_at)
        self.assertTrue(all(g >= 1 for g in gained), f"a survivor served nothing: {gained}")


if __name__ == "__main__":
    unittest.main(verbosity=2)
