"""The stochastic form of a network in array form: one compiled likelihood per padded size.

The maximum-likelihood solve and the exact Hessian of the Kalman filter's negative
log-likelihood cost seconds of compilation each, and a program built from a model's
:meth:`~jaxbox.models.RCModel.rc_form` is specific to its structure: a likelihood-ratio
selection over four models compiled eight of them. Here the network enters as arrays
(:meth:`~jaxbox.models.RCModel.rc_arrays`, evaluated by
:func:`~jaxbox.models._network.rc_from_arrays`), together with the slots of its noise
parameters, its output matrix and its initial covariance, all padded to sizes rounded up
(:data:`ML_BUCKETS`). Every structure of the same padded size then runs the same program.

Padding is inert and exact. A padding state decays on its own (no input, no diffusion, initial
mean and variance 0), so its mean and covariance stay 0 and it never reaches an output; a
padding input column is zero; a padding parameter is held (its coordinate's gradient is zero,
so BFGS never moves it). Networks with a node held at a constant temperature have no array
form here and keep a program of their own (:func:`has_array_form`).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..fit._fit import _round_up
from ..models import RCModel
from ..models._network import rc_from_arrays
from ..simulate._exact import discretize_foh_rc
from ._kalman import process_noise
from ._noise import diffusion_names, measurement_names

__all__ = ["ML_BUCKETS", "has_array_form", "padded_sizes", "ml_arrays", "system_from_arrays"]

#: sizes are rounded up to multiples of these: parameters (physical and noise), states, input
#: columns, edges, heat sources, factors per product
ML_BUCKETS = dict(params=12, states=2, inputs=4, edges=8, sources=8, factors=2)

#: the arrays of one problem, in the order the compiled functions take them
KEYS = (
    "kinds",
    "lower",
    "upper",
    "scale",
    "mask",
    "values",
    "prior_mean",
    "prior_sd",
    "x0_std",
    "sigma",
    "r",
    "out",
    "R",
    "rscale",
    "fk",
    "fa",
    "fb",
    "KG",
    "KH",
    "sk",
    "sa",
    "sb",
    "KS",
    "C",
    "T0",
    "pad",
)
_RC = ("R", "rscale", "fk", "fa", "fb", "KG", "KH", "sk", "sa", "sb", "KS", "C", "T0", "pad")


def has_array_form(model: RCModel) -> bool:
    """Whether the stochastic form of ``model`` has an array form (no node held at a constant
    temperature, whose state would need the held-node discretisation)."""
    return not any(node.constant for node in model.network.nodes)


def padded_sizes(problems) -> dict[str, int]:
    """The padded sizes (see :data:`ML_BUCKETS`) that fit every problem of ``problems``."""
    sizes: dict[str, int] = {}
    for sp in problems:
        own = dict(sp.model.array_sizes(), params=len(sp.param_names), inputs=len(sp.model.inputs))
        for k, v in own.items():
            sizes[k] = max(sizes.get(k, 0), v)
    return {k: _round_up(v, ML_BUCKETS[k]) for k, v in sizes.items()}


def ml_arrays(sp, sizes: dict[str, int]) -> dict[str, np.ndarray]:
    """The arrays of one maximum-likelihood problem (a
    :class:`~jaxbox.stochastic.StochasticProblem`) padded to ``sizes``.

    Returns (``P`` parameters, ``n`` states, ``p`` outputs):

    * ``kinds``, ``lower``, ``upper``, ``scale`` [P]: the bound transform of every parameter
      (``param_names`` order, then padding);
    * ``mask`` [P] (1 for a free parameter), ``values`` [P] (the fixed values, 0 elsewhere);
    * ``prior_mean``, ``prior_sd`` [P] (sd ``inf``: no prior);
    * ``x0_std`` [n] (0 for a padding state);
    * ``sigma`` [n], ``r`` [p]: slots of each state's diffusion (the zero slot for a padding
      state) and of each output's measurement noise in the value vector
      ``v = [parameters, padding, 1, 0]``;
    * ``out`` [p, n]: the output matrix;
    * the network (:meth:`~jaxbox.models.RCModel.rc_arrays`; its ``scale`` as ``rscale``).
    """
    model = sp.model
    names = list(sp.param_names)
    P, n = sizes["params"], sizes["states"]
    slots = names + [f"\0pad{i}" for i in range(P - len(names))] + ["1", "0"]
    where = {s: i for i, s in enumerate(slots)}
    inputs = list(model.inputs) + [f"\0u{i}" for i in range(sizes["inputs"] - len(model.inputs))]
    rc = model.rc_arrays(
        slots,
        states=n,
        inputs=inputs,
        edges=sizes["edges"],
        sources=sizes["sources"],
        factors=sizes["factors"],
    )
    full, mask, values = sp.full_transform()
    extra = P - len(names)
    pm, ps = np.zeros(P), np.full(P, np.inf)
    free_pm, free_ps = sp.prior_arrays()
    for i, name in enumerate(sp.free):
        j = names.index(name)
        pm[j], ps[j] = free_pm[i], free_ps[i]
    n_model = model.n_states
    sigma = np.full(n, where["0"])
    for i, s in enumerate(diffusion_names(model)):
        if s is not None:
            sigma[i] = where[s]
    node_index = {node.name: i for i, node in enumerate(model.network.nodes)}
    out = np.zeros((len(model.outputs), n))
    for k, node in enumerate(m for m in model.network.nodes if m.output):
        out[k, node_index[node.name]] = 1.0
    arrays = dict(
        kinds=np.concatenate([np.asarray(full.kinds), np.ones(extra)]).astype(int),
        lower=np.concatenate([full.lower, np.ones(extra)]),
        upper=np.concatenate([full.upper, np.full(extra, 2.0)]),
        scale=np.concatenate([full.scale, np.ones(extra)]),
        mask=np.concatenate([mask, np.zeros(extra, bool)]),
        values=np.concatenate([values, np.zeros(extra)]),
        prior_mean=pm,
        prior_sd=ps,
        x0_std=np.concatenate([np.asarray(sp.x0_std, float), np.zeros(n - n_model)]),
        sigma=sigma,
        r=np.asarray([where[s] for s in measurement_names(model)]),
        out=out,
        **{("rscale" if k == "scale" else k): v for k, v in rc.items()},
    )
    return {k: arrays[k] for k in KEYS}


def system_from_arrays(v, arrays: dict, dt, hold: str):
    """``(mats, C, D, r, m0, P0)`` of :func:`~jaxbox.stochastic.system` for the value vector
    ``v`` (``[parameters, padding, 1, 0]``, SI) of a problem in array form (traceable)."""
    rc = {("scale" if k == "rscale" else k): arrays[k] for k in _RC}
    A, B, caps, m0 = rc_from_arrays(v, rc)
    Phi, G0, G1 = discretize_foh_rc(A, B, caps, dt)
    if hold == "zoh":
        G1 = jnp.zeros_like(G1)
    sigma = v[arrays["sigma"]]
    Q = process_noise(A, sigma, dt, Phi)
    C = arrays["out"]
    D = jnp.zeros((C.shape[0], B.shape[1]), dtype=B.dtype)
    P0 = jnp.diag(arrays["x0_std"] ** 2)
    return (Phi, G0, G1, Q), C, D, v[arrays["r"]], m0, P0
