"""Test certificates for TLS Dask clusters, made with the ``openssl`` command (shared by the farm
security tests and the documentation's TLS examples)."""

import subprocess
from pathlib import Path


def _openssl(*args: str) -> None:
    subprocess.run(["openssl", *args], check=True, capture_output=True, timeout=60)


def certificates(folder: Path, name: str) -> dict[str, str]:
    """A CA and a certificate it signed for 127.0.0.1 (server and client use), as PEM files."""
    ca_key, ca, key, request, cert = (str(folder / f"{name}-{part}.pem")
                                      for part in ("ca-key", "ca", "key", "req", "cert"))
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", ca_key, "-out", ca, "-days", "2",
             "-subj", f"/CN={name} test CA")
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out", request, "-subj", "/CN=127.0.0.1")
    extensions = folder / f"{name}-ext.cnf"
    extensions.write_text("subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth,clientAuth\n")
    _openssl("x509", "-req", "-in", request, "-CA", ca, "-CAkey", ca_key, "-CAcreateserial", "-out", cert,
             "-days", "2", "-extfile", str(extensions))
    return {"ca": ca, "cert": cert, "key": key}
