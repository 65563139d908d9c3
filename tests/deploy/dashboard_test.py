"""deploy/grafana/ism-dashboard.json against a real ism-server on 127.0.0.1: every metric a panel
or a variable queries, and every label a query groups by, is on the server's /metrics. A metric
renamed in server/metrics.cc would otherwise leave an empty panel that nobody notices.

The server first answers one recognition and one request for a model it does not have, so that
the series that exist only once something was counted (per RPC, per status, per stage) are there;
the stream gauges and counters are there from the start."""
import json
import os
import re
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "clients"))
import scenes  # noqa: E402
from server_process import ServerProcess  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DASHBOARD = os.path.join(HERE, "..", "..", "deploy", "grafana", "ism-dashboard.json")
CLIENT = os.environ.get("ISM_CLIENT_BIN", "")

# Our metric families; a query naming anything else (a typo, a metric of another exporter) fails.
METRIC = re.compile(r"\b((?:ism|process)_[a-z0-9_]+)\b")
GROUPING = re.compile(r"\bby\s*\(([^)]*)\)")
# Prometheus adds these when it scrapes; histogram_quantile needs le.
SCRAPE_LABELS = {"job", "instance", "le"}


def queries(dashboard):
    """(where, PromQL) for every panel target and every query variable."""
    found = []
    for panel in dashboard["panels"]:
        for target in panel.get("targets", []):
            found.append((f'panel "{panel["title"]}" {target["refId"]}', target["expr"]))
    for variable in dashboard["templating"]["list"]:
        if variable["type"] == "query":
            query = variable["query"]
            found.append((f'variable ${variable["name"]}', query["query"] if isinstance(query, dict) else query))
    return found


def exposed(text):
    """Sample name -> the set of label names seen on it, from the Prometheus text format."""
    samples = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        name, _, rest = line.partition("{")
        name = name.split(" ")[0]
        labels = set(re.findall(r'([a-zA-Z_][a-zA-Z0-9_]*)="', rest.partition("}")[0])) if rest else set()
        samples.setdefault(name, set()).update(labels)
    return samples


class DashboardTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not CLIENT:
            raise RuntimeError("ISM_CLIENT_BIN must be set (ctest sets it)")
        with open(DASHBOARD) as f:
            cls.dashboard = json.load(f)
        with ServerProcess() as server, tempfile.TemporaryDirectory() as tmp:
            pcd = os.path.join(tmp, "scene.pcd")
            scenes.write_pcd(pcd, scenes.box_on_floor(), kind="binary")
            base = [CLIENT, "--server", server.address, "--deadline-ms", "120000"]
            for args, expected in ((["recognize", pcd], 0), (["recognize", pcd, "--model", "no-such-model"], 15)):
                done = subprocess.run(base + args, capture_output=True, text=True, timeout=180)
                if done.returncode != expected:
                    raise RuntimeError(f"{args}: exit {done.returncode}, expected {expected}\n"
                                       f"{done.stdout}{done.stderr}{server.log()}")
            cls.samples = exposed(server.metrics())

    def test_every_queried_metric_is_exposed(self):
        checked = 0
        for where, expr in queries(self.dashboard):
            names = METRIC.findall(expr)
            with self.subTest(query=where):
                self.assertTrue(names, f"{where} queries none of the server's metrics: {expr}")
                for name in names:
                    self.assertIn(name, self.samples, f"{where}: {name} is not on /metrics")
                    checked += 1
                grouped = {label.strip() for group in GROUPING.findall(expr) for label in group.split(",")}
                have = set().union(*(self.samples.get(name, set()) for name in names))
                for label in sorted(grouped - SCRAPE_LABELS - {""}):
                    self.assertIn(label, have, f"{where} groups by '{label}', which {names} do not carry")
        print(f"{checked} metric references in {len(queries(self.dashboard))} queries, all on /metrics", flush=True)

    def test_panels_use_the_datasource_variable(self):
        # Imported into any Grafana, the panels follow the Prometheus the user picks.
        for panel in self.dashboard["panels"]:
            if panel["type"] == "row":
                continue
            with self.subTest(panel=panel["title"]):
                self.assertEqual(panel["datasource"]["uid"], "${datasource}")
                self.assertTrue(panel["targets"])

    def test_what_the_operator_needs_is_charted(self):
        exprs = " ".join(expr for _, expr in queries(self.dashboard))
        for needed in ("ism_requests_total", "ism_request_duration_seconds_bucket", "ism_stage_duration_seconds_bucket",
                       "ism_active_streams", "ism_skipped_frames_total", "ism_loaded_models",
                       "process_resident_memory_bytes"):
            self.assertIn(needed, exprs)
        self.assertIn('code!="OK"', exprs)  # errors by status


if __name__ == "__main__":
    unittest.main(verbosity=2)
