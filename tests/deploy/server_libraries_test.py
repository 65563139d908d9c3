"""What ism-server loads: none of the libraries issue 18 took out of the image (PCL's file I/O,
surface and features, VTK, Qt, OpenNI), and nothing that deploy/install-deps.sh --runtime (the
image's runtime stage) would not install. The container test proves the same by running the
image, but takes minutes; this takes a second and names the library."""
import os
import re
import subprocess
import unittest

SERVER = os.environ.get("ISM_SERVER_BIN", "")
SOURCE = os.environ.get("ISM_SOURCE_DIR", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
UNWANTED = re.compile(r"vtk|qt|openni|pcl_io|pcl_surface|pcl_features|pcl_filters|pcl_sample_consensus|boost", re.I)


def loaded_libraries():
    """soname -> path (or 'not found') as the dynamic loader resolves them."""
    out = subprocess.run(["ldd", SERVER], capture_output=True, text=True, check=True).stdout
    libraries = {}
    for line in out.splitlines():
        match = re.match(r"\s*(\S+) => (.+?)(?: \(0x[0-9a-f]+\))?$", line)
        if match:
            libraries[match.group(1)] = match.group(2)
    return libraries


def runtime_packages():
    with open(os.path.join(SOURCE, "deploy", "install-deps.sh")) as f:
        match = re.search(r"^runtime=\(([^)]*)\)", f.read(), re.M)
    return match.group(1).split()


def closure(packages):
    """The packages and everything they depend on, as apt would install them."""
    out = subprocess.run(["apt-cache", "depends", "--recurse", "--no-recommends", "--no-suggests", "--no-conflicts",
                          "--no-breaks", "--no-replaces", "--no-enhances", *packages],
                         capture_output=True, text=True, check=True).stdout
    return {line.strip().strip("<>").split(":")[0] for line in out.splitlines() if not line.startswith(" ")}


def owners(paths):
    """path -> the Debian package holding it (None if none does), from one dpkg query. On
    merged-/usr systems dpkg may know a file under /lib rather than /usr/lib, or the reverse."""
    candidates = {}
    for path in paths:
        names = [path, os.path.realpath(path)]
        for p in list(names):
            if p.startswith("/usr/lib/"):
                names.append(p[len("/usr"):])
            elif p.startswith("/lib/"):
                names.append("/usr" + p)
        candidates[path] = names
    everything = sorted({name for names in candidates.values() for name in names})
    out = subprocess.run(["dpkg", "-S", *everything], capture_output=True, text=True).stdout
    package_of = {}
    for line in out.splitlines():
        package, _, file = line.partition(": ")
        package_of[file] = package.split(":")[0]
    return {path: next((package_of[n] for n in names if n in package_of), None) for path, names in candidates.items()}


class ServerLibrariesTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        if not SERVER:
            raise RuntimeError("ISM_SERVER_BIN must be set (ctest sets it)")
        cls.libraries = loaded_libraries()
        print(f"ism-server loads {len(cls.libraries)} shared libraries", flush=True)

    def test_every_library_resolves(self):
        missing = [name for name, path in self.libraries.items() if path == "not found"]
        self.assertEqual(missing, [])

    def test_no_file_io_rendering_or_sensor_libraries(self):
        unwanted = sorted(name for name in self.libraries if UNWANTED.search(name))
        self.assertEqual(unwanted, [], "ism-server must not load these (the image has none of them)")

    def test_the_runtime_package_list_holds_every_library(self):
        wanted = closure(runtime_packages())
        package_of = owners([path for path in self.libraries.values() if path != "not found"])
        for name, path in sorted(self.libraries.items()):
            package = package_of.get(path)
            with self.subTest(library=name):
                self.assertIsNotNone(package, f"{path} belongs to no Debian package")
                self.assertIn(package, wanted,
                              f"{name} comes from {package}, which install-deps.sh --runtime does not install")


if __name__ == "__main__":
    unittest.main(verbosity=2)
