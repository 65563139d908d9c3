"""Static checks of deploy/: every YAML file parses, the Kubernetes objects fit together (names,
selectors, probes, ports), the server runs non-root on a read-only root filesystem in compose and
Kubernetes alike, and every ISM_* variable the deployment sets is one that ism-server
actually reads (its envname() declarations in server/options.cc), so a renamed flag cannot leave
a ConfigMap silently ignored."""
import glob
import os
import re
import unittest

import yaml

SOURCE = os.environ.get("ISM_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
DEPLOY = os.path.join(SOURCE, "deploy")


def load_all(path):
    with open(path) as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


def server_env_vars():
    with open(os.path.join(SOURCE, "server", "options.cc")) as f:
        names = set(re.findall(r'envname\("(ISM_[A-Z0-9_]+)"\)', f.read()))
    assert names, "server/options.cc declares no envname(): the parsing here is out of date"
    return names


class ManifestsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.env_vars = server_env_vars()
        cls.objects = {}
        for path in sorted(glob.glob(os.path.join(DEPLOY, "k8s", "*.yaml"))):
            for doc in load_all(path):
                cls.objects.setdefault(doc["kind"], []).append((os.path.basename(path), doc))

    def one(self, kind, name="ism-server"):
        matches = [d for f, d in self.objects.get(kind, []) if d["metadata"]["name"] == name
                   and not f.endswith(".patch.yaml")]
        self.assertEqual(len(matches), 1, f"expected one {kind} {name}")
        return matches[0]

    def test_every_object_has_api_version_kind_and_name(self):
        for kind, docs in self.objects.items():
            for file, doc in docs:
                if kind == "Kustomization":
                    continue
                with self.subTest(file=file, kind=kind):
                    self.assertIn("apiVersion", doc)
                    self.assertTrue(doc.get("metadata", {}).get("name"))

    def test_kustomization_lists_existing_files_and_every_base_manifest(self):
        kustomization = load_all(os.path.join(DEPLOY, "k8s", "kustomization.yaml"))[0]
        resources = kustomization["resources"]
        for resource in resources:
            self.assertTrue(os.path.isfile(os.path.join(DEPLOY, "k8s", resource)), resource)
        base = {os.path.basename(p) for p in glob.glob(os.path.join(DEPLOY, "k8s", "*.yaml"))}
        base -= {"kustomization.yaml"} | {p for p in base if p.endswith(".patch.yaml")}
        self.assertEqual(set(resources), base)

    def test_deployment_probes_use_grpc_health_on_the_grpc_port(self):
        container = self.one("Deployment")["spec"]["template"]["spec"]["containers"][0]
        ports = {p["name"]: p["containerPort"] for p in container["ports"]}
        self.assertEqual(ports, {"grpc": 50051, "metrics": 9464})
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            with self.subTest(probe=probe):
                self.assertEqual(container[probe]["grpc"]["port"], 50051)
        for key in ("requests", "limits"):
            self.assertEqual(set(container["resources"][key]), {"cpu", "memory"})

    def test_selectors_match_the_pod_labels(self):
        deployment = self.one("Deployment")
        labels = deployment["spec"]["template"]["metadata"]["labels"]
        for kind, selector in (("Deployment", deployment["spec"]["selector"]["matchLabels"]),
                               ("Service", self.one("Service")["spec"]["selector"]),
                               ("PodDisruptionBudget", self.one("PodDisruptionBudget")["spec"]["selector"]["matchLabels"])):
            with self.subTest(kind=kind):
                self.assertTrue(selector.items() <= labels.items(), f"{selector} does not select {labels}")

    def test_service_is_headless_for_client_side_balancing(self):
        service = self.one("Service")["spec"]
        self.assertEqual(service["clusterIP"], "None")
        self.assertEqual({p["name"]: p["port"] for p in service["ports"]}, {"grpc": 50051, "metrics": 9464})

    def test_hpa_scales_the_deployment_and_keeps_the_pdb_satisfiable(self):
        hpa = self.one("HorizontalPodAutoscaler")["spec"]
        self.assertEqual(hpa["scaleTargetRef"]["kind"], "Deployment")
        self.assertEqual(hpa["scaleTargetRef"]["name"], self.one("Deployment")["metadata"]["name"])
        self.assertLessEqual(hpa["minReplicas"], hpa["maxReplicas"])
        self.assertGreater(hpa["minReplicas"], self.one("PodDisruptionBudget")["spec"]["maxUnavailable"])

    def test_configured_variables_are_ones_the_server_reads(self):
        config = self.one("ConfigMap")["data"]
        self.assertLessEqual(set(config), self.env_vars)
        drain = float(config["ISM_DRAIN_SECONDS"])
        pod = self.one("Deployment")["spec"]["template"]["spec"]
        pause = float(pod["containers"][0]["lifecycle"]["preStop"]["exec"]["command"][-1])
        self.assertLess(pause + drain, pod["terminationGracePeriodSeconds"])
        compose = load_all(os.path.join(DEPLOY, "compose.yaml"))[0]["services"]["ism-server"]
        self.assertLessEqual(set(compose["environment"]), self.env_vars)
        with open(os.path.join(DEPLOY, "Containerfile")) as f:
            containerfile_vars = set(re.findall(r"\b(ISM_[A-Z0-9_]+)=", f.read()))
        self.assertTrue(containerfile_vars)
        self.assertLessEqual(containerfile_vars, self.env_vars)

    def test_server_runs_non_root_with_a_read_only_root_filesystem(self):
        pod = self.one("Deployment")["spec"]["template"]["spec"]
        self.assertTrue(pod["securityContext"]["runAsNonRoot"])
        self.assertNotEqual(pod["securityContext"]["runAsUser"], 0)
        container = pod["containers"][0]["securityContext"]
        self.assertTrue(container["readOnlyRootFilesystem"])
        self.assertFalse(container["allowPrivilegeEscalation"])
        self.assertEqual(container["capabilities"]["drop"], ["ALL"])
        patch = next(d for f, d in self.objects["Deployment"] if f == "models-init-container.patch.yaml")
        init = patch["spec"]["template"]["spec"]["initContainers"][0]["securityContext"]
        self.assertTrue(init["readOnlyRootFilesystem"])
        self.assertNotEqual(init["runAsUser"], 0)

        compose = load_all(os.path.join(DEPLOY, "compose.yaml"))[0]["services"]["ism-server"]
        self.assertIs(compose["read_only"], True)
        self.assertEqual(compose["cap_drop"], ["ALL"])
        self.assertIn("no-new-privileges:true", compose["security_opt"])
        self.assertNotIn("user", compose, "the image's USER is the non-root uid; compose must not override it")
        with open(os.path.join(DEPLOY, "Containerfile")) as f:
            users = re.findall(r"^USER\s+(\S+)", f.read(), re.MULTILINE)
        self.assertEqual(users[-1:], [str(pod["securityContext"]["runAsUser"])],
                         "the runtime stage's USER is the uid the Deployment runs as")

    def test_models_patch_points_the_server_at_the_volume_the_init_container_fills(self):
        patch = next(d for f, d in self.objects["Deployment"] if f == "models-init-container.patch.yaml")
        pod = patch["spec"]["template"]["spec"]
        init_mount = pod["initContainers"][0]["volumeMounts"][0]
        server = pod["containers"][0]
        env = {e["name"]: e["value"] for e in server["env"]}
        mount = server["volumeMounts"][0]
        self.assertEqual(init_mount["name"], mount["name"])
        self.assertEqual(env["ISM_MODELS"], mount["mountPath"])
        self.assertIn(mount["name"], {v["name"] for v in pod["volumes"]})


if __name__ == "__main__":
    unittest.main(verbosity=2)
