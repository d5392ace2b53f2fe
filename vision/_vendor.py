"""Refresh the vendored three.js (the live page's 3D avatar) from the npm registry:
``mimic vendor-three [--version 0.160.0]``.

The page never reaches the network: it loads ``vision/static/three.module.min.js``, which
this command fetches from ``registry.npmjs.org`` (the package's tarball, checked against
the registry's sha512 integrity) together with the package's LICENSE, and writes beside
the page (each file through a temporary file, so a failed refresh leaves the old one).
0.160.0 is the pinned release: it is the last that ships one minified module (670 KB);
later releases split it into unminified files three times that size.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import tarfile
import urllib.request
from pathlib import Path

from control.artifacts import atomic_write

STATIC = Path(__file__).with_name("static")
THREE_VERSION = "0.160.0"
__all__ = ["THREE_VERSION", "vendor_three"]

FILES = {
    "package/build/three.module.min.js": "three.module.min.js",
    "package/LICENSE": "three.LICENSE",
}
REGISTRY = "https://registry.npmjs.org"


def fetch(version: str = THREE_VERSION, registry: str = REGISTRY) -> dict[str, bytes]:
    """The vendored files of three ``version``, by their names in ``vision/static``."""
    with urllib.request.urlopen(f"{registry}/three/{version}", timeout=60) as r:
        dist = json.load(r)["dist"]
    algo, _, want = dist["integrity"].partition("-")
    if algo != "sha512":
        raise ValueError(f"three {version}: the registry's integrity is {algo}, not sha512")
    with urllib.request.urlopen(dist["tarball"], timeout=120) as r:
        blob = r.read()
    if base64.b64encode(hashlib.sha512(blob).digest()).decode() != want:
        raise ValueError(f"{dist['tarball']}: the tarball does not match the registry's sha512")
    out: dict[str, bytes] = {}
    with tarfile.open(fileobj=io.BytesIO(blob), mode="r:gz") as tar:
        for member, name in FILES.items():
            fh = tar.extractfile(member)
            if fh is None:
                raise ValueError(f"three {version}: the package has no {member}")
            out[name] = fh.read()
    return out


def vendor_three(
    version: str = THREE_VERSION, folder: Path = STATIC, registry: str = REGISTRY
) -> list[tuple[Path, int]]:
    """Write three ``version``'s files into ``folder`` (the page's); each path and size."""
    written = []
    for name, data in fetch(version, registry).items():
        with atomic_write(folder / name, "wb") as fh:
            fh.write(data)
        written.append((folder / name, len(data)))
    return written
