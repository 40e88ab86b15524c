"""Standard excitation sequences: PRBS, ROLBS and a constant step, as 0/1 patterns.

* **PRBS** — a maximum-length pseudo-random binary sequence from a linear feedback shift
  register (period ``2ⁿ − 1`` clock periods), held for ``clock`` samples per bit.
* **ROLBS** — a randomly ordered logarithmically distributed binary sequence (the excitation of
  the twin-house and PASLINK experiments): a set of switching durations spread evenly on a
  logarithmic scale between ``shortest`` and ``longest`` samples, each used once "on" and once
  "off" per cycle, the on and the off durations each in a random order, alternating on and
  off; the cycle is repeated (reshuffled) until the horizon is filled. Its power is spread
  evenly over the logarithmic frequency band of the building's time constants, where a PRBS
  concentrates it near its clock frequency.
* **step** — constant on from the first sample (the co-heating test: a constant power).

Each returns a 0/1 pattern [N]; :func:`levels` maps it to powers.
"""

from __future__ import annotations

import numpy as np

__all__ = ["prbs", "rolbs", "step", "levels", "SEQUENCES"]

SEQUENCES = ("prbs", "rolbs", "step")
"""The baseline schedules a design is compared with: PRBS, ROLBS and a constant step."""

#: feedback taps of maximal-length Fibonacci LFSRs, by register length
_TAPS = {
    2: (2, 1),
    3: (3, 2),
    4: (4, 3),
    5: (5, 3),
    6: (6, 5),
    7: (7, 6),
    8: (8, 6, 5, 4),
    9: (9, 5),
    10: (10, 7),
    11: (11, 9),
    12: (12, 11, 10, 4),
    13: (13, 12, 11, 8),
    14: (14, 13, 12, 2),
    15: (15, 14),
    16: (16, 15, 13, 4),
}


def _whole(name: str, value, where: str) -> int:
    """An integer argument of ``where`` (a TypeError naming it otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{where} needs an integer {name}, got {value!r}")
    return int(value)


def prbs(n: int, clock: int = 1, seed: int = 1) -> np.ndarray:
    """Maximum-length PRBS of ``n`` samples, ``clock`` samples per bit (0/1 floats).

    The register is as short as allows ``2ᵏ − 1 ≥ n / clock`` bits (at least 2); ``seed``
    (≥ 1) sets its initial state, i.e. the phase of the sequence.
    """
    n, clock, seed = (_whole(k, v, "prbs") for k, v in (("n", n), ("clock", clock), ("seed", seed)))
    if n < 1 or clock < 1:
        raise ValueError(f"prbs needs n ≥ 1 and clock ≥ 1, got n={n}, clock={clock}")
    bits_needed = -(-n // clock)
    k = 2
    while (1 << k) - 1 < bits_needed and k < max(_TAPS):
        k += 1
    taps = _TAPS[k]
    period = (1 << k) - 1
    state = (int(seed) % period) + 1  # any non-zero state
    bits = []
    for _ in range(bits_needed):
        bits.append(state & 1)
        fb = 0
        for t in taps:
            fb ^= (state >> (k - t)) & 1
        state = (state >> 1) | (fb << (k - 1))
    return np.repeat(np.asarray(bits, dtype=float), clock)[:n]


def rolbs(
    n: int, shortest: int = 1, longest: int = 72, durations: int = 6, seed: int = 0
) -> np.ndarray:
    """ROLBS of ``n`` samples (0/1 floats): switching durations log-spaced in
    ``[shortest, longest]`` samples (``durations`` of them), each once on and once off per
    cycle, in random order (``seed``)."""
    n, shortest, longest, durations, seed = (
        _whole(k, v, "rolbs")
        for k, v in (
            ("n", n),
            ("shortest", shortest),
            ("longest", longest),
            ("durations", durations),
            ("seed", seed),
        )
    )
    if n < 1 or shortest < 1 or longest < shortest or durations < 1 or seed < 0:
        raise ValueError(
            "rolbs needs n ≥ 1, 1 ≤ shortest ≤ longest, durations ≥ 1 and seed ≥ 0, got "
            f"n={n}, shortest={shortest}, longest={longest}, durations={durations}, seed={seed}"
        )
    d = np.unique(np.round(np.geomspace(shortest, longest, durations)).astype(int))
    rng = np.random.default_rng(seed)
    out: list[float] = []
    while len(out) < n:
        # every duration once on and once off per cycle: as much heating as not
        for on, off in zip(rng.permutation(d), rng.permutation(d), strict=True):
            out.extend([1.0] * int(on) + [0.0] * int(off))
    return np.asarray(out[:n], dtype=float)


def step(n: int) -> np.ndarray:
    """Constant on: ``n`` ones (the co-heating test)."""
    n = _whole("n", n, "step")
    if n < 1:
        raise ValueError(f"step needs n ≥ 1, got n={n}")
    return np.ones(n)


def levels(pattern: np.ndarray, low: float, high: float) -> np.ndarray:
    """Powers [W]: ``low`` where the pattern is 0, ``high`` where it is 1."""
    return low + (high - low) * np.asarray(pattern, dtype=float)
