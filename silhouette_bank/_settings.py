"""How a bank is made: the camera ring, the body (and its variants), the renderer, the
descriptor and its learned metric (``BankSettings``), hashed into the bank's key."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

from ._body import BodyShape
from ._camera import CameraRing
from ._descriptor import DEFAULT_DESCRIPTOR, HU_SCALE, Descriptor, get_descriptor

__all__ = ["BANK_VERSION", "METRIC_DIMS", "BankSettings", "robust_settings"]

#: Bump when features or rendering change for the same settings.
#: 2: grid cells sampled to a fraction of a pixel, pose banks; 3: the pose scale; 4: the
#: pose bank's root motion in the same scale; 5: checksums, no shards kept once merged;
#: 6: the merged features stored at half precision (``_bank.FEATURE_DTYPE``); 7: the
#: features and root motion in memory-mapped ``.npy`` files, hashed by blocks
BANK_VERSION = 7

#: dimensions of the learned metric by default, per descriptor (the others: none); the
#: outline's 200 numbers keep more (24: 0.80, 32: 0.80, 48 and 64: 0.82 on the
#: recognition folds)
METRIC_DIMS = {"multigrid": 24, "outline": 48}


@dataclass(frozen=True)
class BankSettings:
    """Everything that changes the bank's numbers: the ring, the body, the renderer, and
    the variants rendered beside the main body.

    ``bodies``: further body shapes; ``shadow``: every body also with a shadow blob at
    its feet. ``descriptor``: what each frame and view is reduced to (``DESCRIPTORS``:
    ``"outline"`` by default, ``"multigrid"``, ``"grid"``, ``"hu"``, or ``"pose"``, the
    avatar's joints projected, which admits no body variants or shadows). The bank then holds
    ``ring.n_views`` views per variant, variant after variant (``variants``): view ``j``
    of the bank is ring view ``j % ring.n_views`` of variant ``j // ring.n_views``.
    Matching takes the best view, so the variants make the match robust to performers
    of other builds and to shadows, at the cost of a bank and a matcher that many times larger."""

    ring: CameraRing = field(default_factory=CameraRing)
    body: BodyShape = field(default_factory=BodyShape)
    renderer: str = "raster"
    bodies: tuple[BodyShape, ...] = ()
    shadow: bool = False
    descriptor: str = DEFAULT_DESCRIPTOR
    #: dimensions of the metric learned from the bank (``_metric.learn_metric``): 0
    #: none; ``None``: the descriptor's default (``METRIC_DIMS``)
    metric: int | None = None

    def __post_init__(self) -> None:
        if self.renderer not in ("raster", "gl"):
            raise ValueError(f"renderer must be 'raster' or 'gl', not {self.renderer!r}")
        get_descriptor(self.descriptor)  # a clear error for an unknown name
        if self.metric is not None and self.metric < 0:
            raise ValueError(f"metric must be a number of dimensions (0: none), not {self.metric}")
        if self.metric and get_descriptor(self.descriptor).kind != "silhouette":
            raise ValueError(
                f"a learned metric is for silhouette descriptors, not {self.descriptor!r}"
            )
        if self.descriptor == "pose" and (self.bodies or self.shadow):
            raise ValueError("a pose bank projects joints: body variants and shadows do not apply")
        if self.renderer == "gl" and (self.bodies or self.shadow):
            raise ValueError("body variants and shadows are rendered by the raster renderer only")

    @property
    def variants(self) -> list[tuple[BodyShape, bool]]:
        """``(body, shadow)`` of each block of ``ring.n_views`` views, in bank order."""
        shapes = [self.body, *self.bodies]
        return [(b, False) for b in shapes] + ([(b, True) for b in shapes] if self.shadow else [])

    @property
    def metric_dims(self) -> int:
        """Dimensions of the learned metric (0: none)."""
        return METRIC_DIMS.get(self.descriptor, 0) if self.metric is None else self.metric

    @property
    def features(self) -> Descriptor:
        """The descriptor object of ``descriptor``."""
        return get_descriptor(self.descriptor)

    @property
    def n_views(self) -> int:
        """Views per frame in the bank: ring views times variants."""
        return self.ring.n_views * len(self.variants)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "ring": self.ring.to_dict(),
            "body": self.body.to_dict(),
            "renderer": self.renderer,
            "hu_scale": [float(x) for x in HU_SCALE],
            "version": BANK_VERSION,
        }
        if self.bodies or self.shadow:  # only then: older banks keep their keys
            out["bodies"] = [b.to_dict() for b in self.bodies]
            out["shadow"] = self.shadow
        if self.descriptor != "hu":  # banks from before the grid have no key: Hu
            out["descriptor"] = self.descriptor
        if self.metric_dims:
            out["metric"] = self.metric_dims
        return out

    def digest(self) -> str:
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()

    @staticmethod
    def from_dict(d: dict[str, Any]) -> BankSettings:
        desc = str(d.get("descriptor", "hu"))
        metric = int(d.get("metric", 0))
        return BankSettings(
            CameraRing(**d["ring"]),
            BodyShape(**d["body"]),
            d["renderer"],
            tuple(BodyShape(**b) for b in d.get("bodies", [])),
            bool(d.get("shadow", False)),
            desc,
            None if metric == METRIC_DIMS.get(desc, 0) else metric,
        )


def robust_settings(base: BankSettings | None = None) -> BankSettings:
    """``base`` (default ``BankSettings()``) with the variants measured to help matching
    performers who are not the avatar (``benchmarks/bench_accuracy.py --variants``):
    bodies 0.9, 1.1 and 1.25 times as wide, each with and without a shadow at the feet
    (8 variants in all)."""
    base = base or BankSettings()
    return dataclasses.replace(
        base,
        bodies=tuple(BodyShape(width=w, height=base.body.height) for w in (0.9, 1.1, 1.25)),
        shadow=True,
    )
