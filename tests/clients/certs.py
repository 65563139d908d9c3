"""A throwaway PKI for the client security tests, made with the openssl command as
tests/service/security_test.cc does: two unrelated CAs, a server certificate valid for
127.0.0.1 and one valid only for the name "ism-server", client certificates from each CA, and
user and admin token files."""
import os
import subprocess

USER_TOKEN = "user-token-3b9d27c4e6a1f508"
ADMIN_TOKEN = "admin-token-c81f4a2e9b7d6053"


def _openssl(*args):
    done = subprocess.run(["openssl", *args], capture_output=True, text=True, timeout=60)
    if done.returncode:
        raise RuntimeError(f"openssl {' '.join(args)} failed:\n{done.stdout}{done.stderr}")


class Pki:
    """Files in `directory`: NAME.crt and NAME.key for each CA and certificate, `tokens` and
    `admin-tokens`; path(NAME) gives a file's path."""

    def __init__(self, directory: str):
        self.directory = directory
        for ca in ("ca", "rogue-ca"):
            _openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-days",
                     "1", "-subj", f"/CN={ca}", "-keyout", self.path(f"{ca}.key"), "-out", self.path(f"{ca}.crt"))
        self._certificate("server", "ca", "subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth")
        self._certificate("named-server", "ca", "subjectAltName=DNS:ism-server\nextendedKeyUsage=serverAuth")
        self._certificate("client", "ca", "extendedKeyUsage=clientAuth")
        self._certificate("rogue-client", "rogue-ca", "extendedKeyUsage=clientAuth")
        self._secret("tokens", f"# user tokens\n{USER_TOKEN}\n")
        self._secret("admin-tokens", f"{ADMIN_TOKEN}\n")

    def path(self, name: str) -> str:
        return os.path.join(self.directory, name)

    def server_flags(self, certificate: str = "server", client_ca: str = "") -> list:
        """ism-server flags for TLS with `certificate`, the token files and, with `client_ca`, mTLS."""
        flags = ["--tls-cert", self.path(f"{certificate}.crt"), "--tls-key", self.path(f"{certificate}.key"),
                 "--token-file", self.path("tokens"), "--admin-token-file", self.path("admin-tokens")]
        if client_ca:
            flags += ["--tls-client-ca", self.path(f"{client_ca}.crt")]
        return flags

    def _certificate(self, name: str, ca: str, extensions: str):
        with open(self.path(f"{name}.ext"), "w") as f:
            f.write(extensions + "\n")
        _openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-subj", f"/CN={name}",
                 "-keyout", self.path(f"{name}.key"), "-out", self.path(f"{name}.csr"))
        _openssl("x509", "-req", "-days", "1", "-in", self.path(f"{name}.csr"), "-CA", self.path(f"{ca}.crt"),
                 "-CAkey", self.path(f"{ca}.key"), "-CAcreateserial", "-extfile", self.path(f"{name}.ext"),
                 "-out", self.path(f"{name}.crt"))

    def _secret(self, name: str, text: str):
        fd = os.open(self.path(name), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(text)
