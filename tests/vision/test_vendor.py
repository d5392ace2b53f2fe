"""``mimic vendor-three``'s fetch, against a registry served here: the files it writes, and
a tarball that does not match the registry's checksum refused with nothing written."""

from __future__ import annotations

import base64
import hashlib
import io
import json
import tarfile
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest

from vision import vendor_three


def _tarball(files: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return buf.getvalue()


def _registry(blob: bytes, integrity: str) -> tuple[ThreadingHTTPServer, str]:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: Any) -> None:
            pass

        def do_GET(self) -> None:
            if self.path == "/three/9.9.9":
                tarball = f"http://127.0.0.1:{self.server.server_address[1]}/three.tgz"
                body = json.dumps({"dist": {"integrity": integrity, "tarball": tarball}}).encode()
            elif self.path == "/three.tgz":
                body = blob
            else:
                self.send_error(404)
                return
            self.send_response(200)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}"


def test_the_module_and_licence_are_written_from_a_checked_tarball(tmp_path: Path) -> None:
    blob = _tarball(
        {
            "package/build/three.module.min.js": b"export const REVISION = '999';",
            "package/LICENSE": b"The MIT License",
            "package/build/three.cjs": b"not wanted",
        }
    )
    good = "sha512-" + base64.b64encode(hashlib.sha512(blob).digest()).decode()
    server, url = _registry(blob, good)
    try:
        written = vendor_three("9.9.9", tmp_path, url)
        assert sorted(p.name for p, _ in written) == ["three.LICENSE", "three.module.min.js"]
        assert (tmp_path / "three.module.min.js").read_bytes().startswith(b"export const")
        assert len(list(tmp_path.iterdir())) == 2
    finally:
        server.shutdown()
        server.server_close()
    bad = "sha512-" + base64.b64encode(hashlib.sha512(b"other").digest()).decode()
    server, url = _registry(blob, bad)
    try:
        with pytest.raises(ValueError, match="does not match the registry's sha512"):
            vendor_three("9.9.9", tmp_path / "new", url)
        assert not (tmp_path / "new").exists()
    finally:
        server.shutdown()
        server.server_close()
