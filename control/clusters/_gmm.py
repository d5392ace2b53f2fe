"""Spherical Gaussian mixtures by EM with the number of clusters chosen by BIC (Lee §4.2.1).

scikit-learn's ``GaussianMixture(covariance_type="spherical")`` does the EM. Its seeds are
chosen here, automatically and reproducibly, in place of the paper's 15-25 keyframes
picked by hand: ``"keyframes"`` runs k-means++ (seeded) and a few Lloyd steps and then
snaps every centre to its nearest frame, so the initial means are real poses, as the
paper's keyframes were. ``"random"`` is the baseline the paper mentions: several random
restarts from data points, keeping the best log-likelihood.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..jobs import JobStore, cluster_address, run_jobs
from ..motion import FloatArray

__all__ = [
    "FIT_KEYS",
    "SEEDINGS",
    "Clustering",
    "decorrelation_frames",
    "effective_bic",
    "fit_arrays",
    "fit_mixture",
    "fit_of",
    "keyframe_seeds",
    "select_by_bic",
]

SEEDINGS = ("keyframes", "random")


@dataclass(frozen=True, eq=False)
class Clustering:
    """A fitted mixture and its summary.

    Attributes
    ----------
    labels : (n,) cluster of every frame (the most probable component).
    posterior : (n,) probability of that cluster given the frame.
    means : (K, d). variances : (K,). weights : (K,).
    log_likelihood : the maximised mixture log-likelihood (sum over frames).
    bic : ``2 L - m log n`` (the paper's sign: larger is better), m the free parameters
        (means, variances and weights).
    n_params : m.
    seeding : how EM was started. seeds : (K,) frames used as initial means (keyframes).
    """

    labels: NDArray[np.int64]
    posterior: FloatArray
    means: FloatArray
    variances: FloatArray
    weights: FloatArray
    log_likelihood: float
    bic: float
    n_params: int
    seeding: str
    seeds: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def k(self) -> int:
        return int(self.means.shape[0])

    def sizes(self) -> NDArray[np.int64]:
        return np.bincount(self.labels, minlength=self.k).astype(np.int64)


def _squared_distances(x: FloatArray, centres: FloatArray, elems: int = 1 << 23) -> FloatArray:
    """Every row's squared distance to every centre, ``elems`` differences at a time.

    Each entry is summed exactly as the whole ``(n, k, d)`` array would sum it, without that
    array (2.7 GB at 500,000 frames).
    """
    n, k = x.shape[0], centres.shape[0]
    step = max(1, elems // max(1, k * x.shape[1]))
    out = np.empty((n, k), dtype=np.result_type(x, centres))
    for a in range(0, n, step):
        out[a : a + step] = ((x[a : a + step, None, :] - centres[None]) ** 2).sum(-1)
    return out


def keyframe_seeds(x: FloatArray, k: int, seed: int = 0) -> NDArray[np.int64]:
    """``k`` distinct frames to start EM from: k-means centres snapped to their nearest frame."""
    from sklearn.cluster import KMeans  # (here: a second of import a cached layer never needs)

    km = KMeans(n_clusters=k, n_init=1, max_iter=20, random_state=seed).fit(x)
    d = _squared_distances(x, km.cluster_centers_) if x.shape[0] * k < 4e6 else None
    frames: list[int] = []
    for c in range(k):
        col = d[:, c] if d is not None else ((x - km.cluster_centers_[c]) ** 2).sum(axis=1)
        order = np.argsort(col)
        for f in order:  # distinct frames
            if int(f) not in frames:
                frames.append(int(f))
                break
    return np.array(frames, dtype=np.int64)


def fit_mixture(
    x: FloatArray,
    k: int,
    seeding: str = "keyframes",
    seed: int = 0,
    restarts: int = 5,
    max_iter: int = 200,
    means_init: FloatArray | None = None,
) -> Clustering:
    """Fit a ``k``-component spherical mixture to the rows of ``x`` (EM started from
    ``means_init`` where given: a fit of a sample of the same states, say)."""
    from sklearn.mixture import GaussianMixture

    if seeding not in SEEDINGS:
        raise ValueError(f"seeding must be one of {', '.join(SEEDINGS)}, not {seeding!r}")
    n = x.shape[0]
    if not 1 <= k <= n:
        raise ValueError(f"k must lie in 1..{n}, not {k}")
    seeds = np.zeros(0, dtype=np.int64)
    common: dict[str, Any] = {
        "covariance_type": "spherical",
        "max_iter": max_iter,
        "random_state": seed,
        "reg_covar": 1e-6,
    }
    if means_init is not None:
        if means_init.shape != (k, x.shape[1]):
            raise ValueError(f"means_init must be ({k}, {x.shape[1]}), not {means_init.shape}")
        gm = GaussianMixture(k, means_init=means_init, **common)
    elif seeding == "keyframes":
        seeds = keyframe_seeds(x, k, seed)
        gm = GaussianMixture(k, means_init=x[seeds], **common)
    else:
        gm = GaussianMixture(k, init_params="random_from_data", n_init=restarts, **common)
    gm.fit(x)
    resp = gm.predict_proba(x)
    labels = np.argmax(resp, axis=1).astype(np.int64)
    ll = float(gm.score(x) * n)
    return Clustering(
        labels=labels,
        posterior=resp[np.arange(n), labels],
        means=gm.means_,
        variances=np.asarray(gm.covariances_, dtype=np.float64),
        weights=gm.weights_,
        log_likelihood=ll,
        bic=-float(gm.bic(x)),
        n_params=int(gm._n_parameters()),
        seeding=seeding,
        seeds=seeds,
    )


#: the arrays a ``Clustering`` is kept as (``fit_arrays``)
FIT_KEYS = (
    "labels",
    "posterior",
    "means",
    "variances",
    "weights",
    "log_likelihood",
    "bic",
    "n_params",
    "seeding",
    "seeds",
)


def fit_arrays(c: Clustering) -> dict[str, np.ndarray]:
    """``c`` as arrays (a ``JobStore``'s part): ``fit_of`` gives it back, number for
    number."""
    return {k: np.asarray(getattr(c, k)) for k in FIT_KEYS}


def fit_of(a: dict[str, np.ndarray]) -> Clustering:
    return Clustering(
        labels=a["labels"],
        posterior=a["posterior"],
        means=a["means"],
        variances=a["variances"],
        weights=a["weights"],
        log_likelihood=float(a["log_likelihood"]),
        bic=float(a["bic"]),
        n_params=int(a["n_params"]),
        seeding=str(a["seeding"]),
        seeds=a["seeds"],
    )


def decorrelation_frames(x: FloatArray, clip_start: NDArray[np.int64], max_lag: int = 240) -> int:
    """Frames after which a motion no longer predicts itself: the first lag at which the
    autocorrelation of the standardised states (pooled over dimensions, within clips)
    falls below 1/e."""
    z = (x - x.mean(axis=0)) / np.maximum(x.std(axis=0), 1e-12)
    for lag in range(1, max_lag + 1):
        num = den = 0.0
        for a, b in itertools.pairwise(clip_start):
            seg = z[a:b]
            if seg.shape[0] > lag:
                num += float(np.sum(seg[:-lag] * seg[lag:]))
                den += float(np.sum(seg[:-lag] ** 2))
        if den == 0.0 or num / den < np.exp(-1.0):
            return lag
    return max_lag


def effective_bic(fit: Clustering, n: int, n_eff: float) -> float:
    """BIC with the sample size of independent observations: frames ``d`` apart are
    correlated, so ``n`` frames carry about ``n / d`` observations' worth of evidence:
    ``2 L n_eff / n - m log n_eff``."""
    return 2.0 * fit.log_likelihood * n_eff / n - fit.n_params * np.log(n_eff)


def _fit_job(shared: tuple[FloatArray, str, int], k: int) -> Clustering:
    """One cluster job: the mixture of ``k`` components (``select_by_bic``)."""
    x, seeding, seed = shared
    return fit_mixture(x, k, seeding=seeding, seed=seed)


def select_by_bic(
    x: FloatArray,
    ks: Sequence[int],
    seeding: str = "keyframes",
    seed: int = 0,
    clip_start: NDArray[np.int64] | None = None,
    cluster: str | None = None,
    n_eff: float | None = None,
    progress: Callable[[int, int], None] | None = None,
    store: JobStore | None = None,
) -> tuple[Clustering, list[Clustering], dict[str, object]]:
    """Fit every ``k`` in ``ks``; return the best, all fits in order, and the curve.
    The fits are made here, or as jobs (one a ``k``) on the Dask cluster that
    ``cluster`` (or ``$MIMIC_CLUSTER``: ``control.jobs``) names.

    With ``clip_start`` the choice uses ``effective_bic`` (frames are not independent:
    plain BIC keeps rising with k on motion data); without, plain BIC as in the paper.
    ``n_eff``: ``x`` is a sample of states whose effective size is this (their
    decorrelation measured on them all); the choice is then by ``effective_bic`` with it,
    each fit's likelihood per state standing for the whole's. The curve holds ``k``,
    ``bic``, ``bic_effective`` (or None), the log-likelihood and the decorrelation length.
    ``progress(done, len(ks))`` is called as each fit comes in. With ``store`` each fit
    is kept as it comes (job ``i``: ``ks[i]``), and those kept before are read back.
    """
    address = cluster_address(cluster)
    got: dict[int, Clustering] = {}
    if store is not None:
        got = {i: fit_of(a) for i, a in store.done(len(ks), FIT_KEYS).items()}
    todo = [i for i in range(len(ks)) if i not in got]

    def take(j: int, fit: Clustering) -> None:
        got[todo[j]] = fit
        if store is not None:
            store.save(todo[j], fit_arrays(fit))
        if progress is not None:
            progress(len(got), len(ks))

    if address is None:
        for j, i in enumerate(todo):
            take(j, fit_mixture(x, ks[i], seeding=seeding, seed=seed))
    else:  # one job a k, the states sent to each worker once
        jobs = [ks[i] for i in todo]
        run_jobs(_fit_job, jobs, take, cluster=address, shared=(x, seeding, seed))
    fits = [got[i] for i in range(len(ks))]
    best, curve = _by_bic(x, fits, clip_start, n_eff)
    return best, fits, curve


def _by_bic(
    x: FloatArray,
    fits: list[Clustering],
    clip_start: NDArray[np.int64] | None,
    n_eff: float | None,
) -> tuple[Clustering, dict[str, object]]:
    """The best of the ``fits`` of ``x`` and the curve (``select_by_bic``)."""
    n = x.shape[0]
    curve: dict[str, object] = {
        "k": [f.k for f in fits],
        "bic": [f.bic for f in fits],
        "log_likelihood": [f.log_likelihood for f in fits],
    }
    if n_eff is not None:
        eff = [effective_bic(f, n, n_eff) for f in fits]
        best = fits[int(np.argmax(eff))]
        curve["bic_effective"] = eff
        curve["effective_states"] = n_eff
    elif clip_start is None:
        best = max(fits, key=lambda c: c.bic)
        curve["bic_effective"] = None
    else:
        d = decorrelation_frames(x, clip_start)
        eff = [effective_bic(f, n, n / d) for f in fits]
        best = fits[int(np.argmax(eff))]
        curve["bic_effective"] = eff
        curve["decorrelation_frames"] = d
    curve["chosen_k"] = best.k
    return best, curve
