"""Merging a frame rendered in shards (split by samples) into the one estimate it stands for.

Shard ``k`` rendered ``n_k`` samples per pixel with its own seed and returned its pixel means
``m_k`` (box filter: each pixel is the plain mean of its samples) and, with moments, the variance
``v_k`` of that mean (``s²/P`` over its P passes, ``render/api.py``). With ``N = Σ n_k``:

    m = Σ (n_k / N) · m_k          the mean of all N samples per pixel: exactly what one render
                                   of N samples computes (other random numbers)
    v = Σ (n_k / N)² · v_k         the variance of that mean: the shards are independent

so ``pavonine compare --method stat`` treats a merged frame like a single render of N samples.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def merge_means(means: Sequence[np.ndarray], samples: Sequence[int]) -> np.ndarray:
    """Σ (n_k / N) m_k, accumulated in float64."""
    total = float(sum(samples))
    out = np.zeros(np.shape(means[0]), dtype=np.float64)
    for mean, n in zip(means, samples, strict=True):
        out += (n / total) * np.asarray(mean, dtype=np.float64)
    return out.astype(np.float32)


def merge_variances(variances: Sequence[np.ndarray], samples: Sequence[int]) -> np.ndarray:
    """Σ (n_k / N)² v_k: the variance of the merged mean of independent shards."""
    total = float(sum(samples))
    out = np.zeros(np.shape(variances[0]), dtype=np.float64)
    for variance, n in zip(variances, samples, strict=True):
        out += (n / total) ** 2 * np.asarray(variance, dtype=np.float64)
    return out.astype(np.float32)
