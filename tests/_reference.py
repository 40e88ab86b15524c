"""Shared test helpers: the independent simulation oracle and a synthetic single-zone building.

The oracle (:func:`van_loan_states`) does not use jaxbox's simulators: it takes the matrix
exponential of the Van Loan block matrix with scipy and steps the states in numpy, exact for
inputs linear between samples.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from jaxbox.data import Dataset
from jaxbox.simulate import simulate_arrays

#: parameters of a ZonWalIntInf building for the synthetic tests (SI, °C)
ZONWALINTINF_TRUTH = {
    "C_zon": 3.0e6,
    "C_wal": 4.0e7,
    "C_int": 1.5e7,
    "R_wal": 0.012,
    "R_int": 0.002,
    "R_inf": 0.02,
    "gA": 2.5,
    "T_zon0": 26.0,
    "T_wal0": 19.0,
    "T_int0": 24.0,
}


def van_loan_states(model, theta, data) -> np.ndarray:
    """Exact states at the samples [N, n] of ``model`` with parameters ``theta`` over ``data``."""
    A, B, _, _ = (np.asarray(m) for m in model.state_space(theta))
    n, m = B.shape
    M = np.zeros((n + 2 * m, n + 2 * m))
    M[:n, :n], M[:n, n : n + m], M[n : n + m, n + m :] = A * data.step, B * data.step, np.eye(m)
    E = scipy.linalg.expm(M)
    Phi, G0, G1 = E[:n, :n], E[:n, n : n + m], E[:n, n + m :]
    u = data.array(list(model.inputs))
    x = np.empty((len(u), n))
    x[0] = [theta[node.T0] for node in model.network.nodes]
    for k in range(len(u) - 1):
        x[k + 1] = Phi @ x[k] + G0 @ u[k] + G1 @ (u[k + 1] - u[k])
    return x


def van_loan_outputs(model, theta, data) -> np.ndarray:
    """Exact outputs at the samples [N, p] (see :func:`van_loan_states`)."""
    _, _, C, D = (np.asarray(m) for m in model.state_space(theta))
    return van_loan_states(model, theta, data) @ C.T + data.array(list(model.inputs)) @ D.T


def synthetic_building(model, theta, n=240, seed=0, noise=0.0, step=3600.0) -> Dataset:
    """``n`` samples every ``step`` s of a single-zone model with inputs ``T_amb``, ``Q_hea``,
    ``I_glo_hor`` (daily cycles, random heating) and its output ``T_zon`` plus white noise of
    standard deviation ``noise`` [K] (seeded)."""
    t = np.arange(n) * step
    rng = np.random.default_rng(seed)
    day = 2 * np.pi * t / 86400
    u = {
        "T_amb": 12 + 6 * np.sin(day - 2) + rng.normal(0, 0.3, n),
        "Q_hea": 600.0 * (rng.random(n) > 0.5),
        "I_glo_hor": np.maximum(0, 450 * np.sin(day)),
    }
    U = np.stack([u[k] for k in model.inputs], axis=1)
    y = np.asarray(simulate_arrays(model, theta, t, U)[0][:, 0]) + noise * rng.normal(size=n)
    return Dataset.from_arrays(t, {**u, "T_zon": y})
