"""The live view serves a page and an MJPEG stream on localhost."""

from __future__ import annotations

import urllib.request

import numpy as np

from vision._live import LiveView


def test_page_and_stream() -> None:
    view = LiveView(port=0)
    try:
        assert view.url.startswith("http://127.0.0.1:")
        view.update(np.full((24, 32, 3), 200, dtype=np.uint8))
        with urllib.request.urlopen(view.url, timeout=5) as r:
            assert b"/stream" in r.read()
        with urllib.request.urlopen(view.url + "stream", timeout=5) as r:
            head = r.read(200)
        assert b"--frame" in head and b"\xff\xd8" in head  # a JPEG follows the boundary
    finally:
        view.close()
