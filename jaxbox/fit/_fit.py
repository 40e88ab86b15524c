"""Batched multistart Levenberg–Marquardt: every start of a problem in one compiled call.

All starts (and, through :func:`solve_jobs`, several datasets of the same length and model
variants of the same shape) form one batch that a single compiled ``lax.while_loop`` iterates;
a start that has terminated is frozen while the others go on, so each start's result does not
depend on the batch it ran in. The solve is compiled ahead of time once per problem *structure*
— model structure, free/fixed split, transform kinds, simulator, solver settings and array
shapes. Data, bounds, fixed values and starts are arguments, so a second dataset of the same
length, new bounds or new starts reuse the compiled executable (``compile_s == 0``).

One iteration
-------------
With the exact simulator each iteration evaluates, for every start at once, the cost ``Σ r²``,
the gradient ``g = Jᵀr`` and the Gram matrix ``H = JᵀJ`` of the weighted residuals in one pass
over the data: the discrete matrices come from a symmetric eigendecomposition (their derivatives
in closed form), and the sensitivities of the state to the ``p`` coordinates travel with the state
as an ``n × p`` matrix (:func:`~jaxbox.simulate._exact.normal_equations`). The Jacobian is never
stored: the tangents are held one chunk of samples at a time. On an accelerator, where a
sequential scan leaves the device idle, a narrow batch runs parallel in time instead (two
associative scans over the samples, :func:`~jaxbox.simulate._parallel.normal_equations_parallel`;
:func:`~jaxbox.simulate._parallel.prefer_parallel` decides). ``simulator="diffrax"`` builds ``J``
with ``jax.jacfwd`` through Kvaerno5 at fixed steps instead.

The step
--------
Levenberg–Marquardt in the form of Moré (1978): the coordinates are scaled by the running maximum
of the column norms of ``J`` (so the method does not depend on how each coordinate is scaled),
the damped normal equations ``(Hₛ + λI) δₛ = −gₛ`` are solved by Cholesky, and λ follows the
gain ratio ``ρ`` (actual over predicted reduction) as in Nielsen (1999). A trial with ``ρ > 10⁻⁴``
is accepted.

Termination (per start)
-----------------------
* ``converged``: an accepted step whose actual and predicted reductions of the cost are both at
  most ``rtol · cost + atol`` (the ``ftol`` test of MINPACK), or a damping that grows beyond
  10¹⁶ without any reduction (the cost cannot be reduced at machine precision);
* ``max_steps``: the iteration cap, counting rejected trials;
* ``nonfinite``: the start itself cannot be evaluated.
"""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jax import lax
from jaxtyping import Float

from .. import _compiled
from .._compiled import jit
from .._defaults import DEFAULT_HOMOTOPY, DEFAULT_MAX_STEPS
from .._derivatives import value_and_jacfwd
from .._exported import compile_program
from ..simulate._extend import extend_times, hold_rows
from ..simulate._parallel import _PARALLEL_BATCH, normal_equations_auto, prefer_parallel
from ._problem import FitError, Problem
from ._result import FitResult, StartReport
from ._solver import LevenbergMarquardt
from ._starts import sample_starts
from ._transforms import position_in_bounds, two_sided

__all__ = [
    "solve_starts",
    "solve_jobs",
    "check_homotopy",
    "compile_cache_info",
    "clear_compile_cache",
]


#: relative tolerance of the stages of a continuation before the last (see :func:`_multistart`)
STAGE_RTOL = 1e-3
#: the tolerance to which ``polish=k`` (:func:`solve_jobs`) solves every start before its k
#: best go on; they go on to the fit's own ``rtol`` times POLISH_TIGHTER: a solve restarted near
#: an optimum stops at the first steps that gain less than ``rtol`` (its damping starts afresh),
#: short of where the solve that came the whole way stops
POLISH_RTOL = 1e-3
POLISH_TIGHTER = 1e-2
#: a bounded coordinate this close to a bound (as a fraction of the bounds) is released
EDGE = 1e-3

#: termination codes of the batched solve
CONVERGED, MAX_STEPS, NONFINITE, RUNNING = 0, 1, 2, -1
_STATUS = {CONVERGED: "converged", MAX_STEPS: "max_steps", NONFINITE: "nonfinite"}


def compile_cache_info() -> dict:
    """Compiled functions kept (``entries``: those of the fit), and the process-wide number of
    compilations and cache hits (see :mod:`jaxbox._compiled`)."""
    return _compiled.info("fit")


def clear_compile_cache() -> None:
    """Drop every compiled function (of the fit and of every other room)."""
    _compiled.clear()


def solver_key(solver) -> object:
    """A hashable stand-in for a solver (a cache and grouping key): the solver itself, or its
    type and text where it holds arrays."""
    try:
        hash(solver)
    except TypeError:
        return (type(solver).__module__, type(solver).__qualname__, repr(solver))
    return solver


def check_homotopy(gains) -> tuple[float, ...]:
    """The observer gains of a continuation, checked: each in (0, 1], strictly decreasing
    (``()`` or ``None``: no continuation, the output-error problem from the start)."""
    if gains is None:
        return ()
    if isinstance(gains, str) or not hasattr(gains, "__iter__"):
        raise FitError(
            f"homotopy must be a sequence of observer gains in (0, 1], strictly decreasing "
            f"(e.g. {DEFAULT_HOMOTOPY}), or () for none; got {gains!r}"
        )
    out = tuple(float(g) for g in gains)
    falling = all(b < a for a, b in zip(out, out[1:], strict=False))
    if any(not (0.0 < g <= 1.0) for g in out) or not falling:
        raise FitError(
            f"homotopy gains must lie in (0, 1] and strictly decrease (e.g. "
            f"{DEFAULT_HOMOTOPY}); got {out}"
        )
    return out


#: most starts iterated together on an accelerator (memory: a slot holds its normal equations)
_ACCELERATOR_SLOTS = 16384
#: most starts iterated together in one queue on a CPU (see :func:`default_slots`)
_CPU_SLOTS = 8
#: starts iterated together on an accelerator where the fit runs parallel in time
_ACCELERATOR_NARROW = 256


def default_slots(n_starts: int, platform: str | None = None, *, parallel: bool = False) -> int:
    """Starts iterated together.

    On a CPU: at most :data:`_CPU_SLOTS`. An iteration costs about the same per slot for 4 or
    64 slots (the vector units work along a start's parameters, not across starts), while the
    last round of a queue leaves slots idle until its slowest start ends: fewer slots idle less.
    Measured on the 2-core CPU of ``benchmarks/RESULTS.md`` (two parts side by side), against
    the earlier 16 to 128 slots: the 14-parameter fit, 1024 starts, 24.2 s instead of 35.3 s
    (64 slots); a structure search's batch of eight 15–18-parameter variants, 5.4 s instead of
    6.9 s (16 slots), 93 % of the computed steps of use instead of 86 %. On a GPU or TPU the
    sequential scan over time costs about the same for 1 or 10⁴ slots, so every start runs at
    once, up to 16384 slots; but where the normal equations of :data:`_ACCELERATOR_NARROW`
    members run parallel in time (``parallel``, see
    :func:`~jaxbox.simulate._parallel.prefer_parallel`), an iteration's cost grows with the
    slots, and up to 1024 starts go through that many slots that refill (on an H100, 1024 starts
    of the 14-parameter model in 1.40 s against 1.85 s all at once, ``benchmarks/GPU.md``).

    Args:
        n_starts: starts in the batch.
        platform: ``"cpu"``, ``"gpu"``, ``"tpu"``; default: JAX's default backend.
        parallel: whether a batch of :data:`_ACCELERATOR_NARROW` members runs parallel in time.
    """
    platform = jax.default_backend() if platform is None else platform
    if platform != "cpu":
        if parallel and n_starts <= _PARALLEL_BATCH:
            return int(max(1, min(n_starts, _ACCELERATOR_NARROW)))
        return int(max(1, min(n_starts, _ACCELERATOR_SLOTS)))
    return int(max(1, min(n_starts, _CPU_SLOTS)))


#: the solver reads each slot's normal equations from the batch evaluation (see _multistart)
_FROM_BATCH = {"normal_equations": lambda y, args: args}


def _multistart(
    solver: LevenbergMarquardt,
    lin,
    z0,
    *,
    max_steps: int,
    start_counts: Sequence[int] | None = None,
    slot_counts: Sequence[int] | None = None,
    routes: Sequence[Sequence[float]] = ((),),
    release=None,
    active=None,
    routed=None,
    rtol=None,
):
    """Every start of ``z0`` [S, p] through ``solver``, a fixed number of *slots* at a time.

    Each iteration evaluates the normal equations of every slot at once — ``lin(Z [B, p],
    idx [B], gain [B] | None) -> (Σ r² [B], Jᵀr [B, p], JᵀJ [B, p, p])``, ``idx`` naming the
    start each slot works on and ``gain`` the observer gain of its stage (see
    :func:`~jaxbox.simulate._exact.normal_equations`) — and then advances each slot by one
    ``solver.step`` (under ``vmap``; the step reads its slot's evaluation through
    ``options["normal_equations"]``).

    Each start is solved once along each of the ``routes``. A route is a sequence of observer
    gains, the stages of a continuation, followed by the output-error problem itself (gain 0);
    ``()`` is the output-error problem alone. A stage ends when ``solver.terminate`` says so (the
    stages before the last at the looser tolerance :data:`STAGE_RTOL`) or at ``max_steps``, and
    the next stage starts where it ended (``solver.init``). With ``release = (bounded [S, p],
    position, anchor [S, p])``, a route that ends with bounded coordinates (``bounded``) within
    :data:`EDGE` of a bound (``position(Z) -> [B, p]``, 0 … 1 in the bounds) gets one more
    output-error stage from that point with those coordinates set halfway (in internal
    coordinates) between their start values and ``anchor``, the problem's guess (see
    :func:`_anchors`; the guess itself where the start was on a bound): the logistic transform
    freezes a coordinate near its bound, and the data may want it elsewhere.
    The route ends at the better of the two.

    ``active`` (a traced bool [S]): the starts solved; the others (the padding of a bucketed
    batch, or the starts a polishing pass leaves, see :func:`solve_jobs`) are never loaded into
    a slot, and their results are NaN. ``routed`` (a traced bool [S]): the starts solved along
    every route; the others along the first route only (their other routes are never loaded
    into a slot, and count no steps). ``rtol`` (traced [S]): each start's relative tolerance
    (default ``solver.rtol``): its routes' last stages end at it, the stages before at it or
    :data:`STAGE_RTOL`, whichever is looser.

    A slot whose route has ended takes the next (start, route) of its group (``slot_counts``
    slots for each group of ``start_counts`` consecutive starts), so the batch stays busy until
    the queue is empty; each start's result does not depend on the batch it ran in. Traceable
    (call it under ``jax.jit``). Returns ``(z [S, p], cost [S], code [S], steps [S])`` of the
    best route of each start (the lowest finite cost); ``steps`` counts every stage of every
    route, ``code`` is that of the best route's last stage (``MAX_STEPS``: it reached the cap);
    and the iterations of the loop (each advances every slot by one step).
    """
    n_starts, p = z0.shape
    dtype = z0.dtype
    start_counts = tuple(start_counts or (n_starts,))
    slot_counts = tuple(slot_counts or (n_starts,))
    n_routes = len(routes)
    # the stages of every route, one after the other, then the release stage
    gains, first_stage, last_stage = [], [], []
    for route in routes:
        first_stage.append(len(gains))
        gains.extend(float(g) for g in route)
        gains.append(0.0)
        last_stage.append(len(gains) - 1)
    release_stage = len(gains)
    gains.append(0.0)
    gain_of = jnp.asarray(gains, dtype)
    continued = any(len(r) for r in routes)
    first_stage, last_stage = jnp.asarray(first_stage), jnp.asarray(last_stage)
    # members: (start, route) pairs, the routes of a start next to each other
    member_counts = tuple(c * n_routes for c in start_counts)
    n_members = n_starts * n_routes
    n_groups = len(member_counts)
    batch = sum(slot_counts)
    group = np.repeat(np.arange(n_groups), slot_counts)
    first = np.concatenate([[0], np.cumsum(member_counts)[:-1]])
    slot_first = np.concatenate([[0], np.cumsum(slot_counts)[:-1]])
    end = jnp.asarray(first + np.asarray(member_counts))
    # the queue: position i of a group's queue holds member order[i]. The longer routes (the
    # continuation's stages) go first, so that none of them starts near the end of the queue and
    # leaves the other slots idle while it runs; the members not solved (``active``, ``routed``)
    # go last, past the group's end
    order = jnp.arange(n_members)
    if n_routes > 1 or active is not None:
        member = np.arange(n_members)
        member_group = np.repeat(np.arange(n_groups), member_counts)
        solved = jnp.ones(n_members, bool)
        if active is not None:
            solved = jnp.asarray(active, bool)[member // n_routes]
        if routed is not None and n_routes > 1:
            solved = solved & (
                (member % n_routes == 0) | jnp.asarray(routed, bool)[member // n_routes]
            )
        late = (~solved).astype(jnp.int32) * 2 + ((member % n_routes == 0) & (n_routes > 1))
        order = jnp.argsort(member_group * 4 + late, stable=True)
        n_solved = jax.ops.segment_sum(
            solved.astype(jnp.int32), jnp.asarray(member_group), num_segments=n_groups
        )
        end = jnp.minimum(end, jnp.asarray(first) + n_solved)
    pos0 = np.asarray(first[group] + np.arange(batch) - slot_first[group])
    idx0 = order[pos0]
    tags = frozenset()

    # each start's tolerance; the stages before a route's last end at a looser one (their
    # optimum is a waypoint)
    if rtol is None:
        rtol = jnp.full((n_starts,), solver.rtol, dtype)
    rtol = jnp.asarray(rtol, dtype)

    def init(z):
        return solver.init(None, z, None, _FROM_BATCH, None, None, tags)

    def step(y, state, evaluation, tol):
        # the tolerance is a leaf of the solver: each slot steps with its own
        own = eqx.tree_at(lambda s: s.rtol, solver, tol)
        return own.step(None, y, evaluation, _FROM_BATCH, state, tags)[:2]

    def terminate(y, state):
        return solver.terminate(None, y, None, _FROM_BATCH, state, tags)

    def where(mask, a, b):
        return jax.tree_util.tree_map(
            lambda x, y: jnp.where(mask.reshape((batch,) + (1,) * (x.ndim - 1)), x, y), a, b
        )

    def trapped(y, start):
        """Bounded coordinates within EDGE of a bound: [B, p]."""
        if release is None:
            return jnp.zeros(y.shape, bool)
        bounded, position, _ = release
        return bounded[start] & _near_edge(position(y))

    # where a trapped coordinate of each start is released to (fixed per start): halfway from
    # its start value to the guess, or the guess itself where the start was on a bound
    if release is not None:
        bounded, position, anchor = release
        release_to = jnp.where(bounded & _near_edge(position(z0)), anchor, 0.5 * (z0 + anchor))

    stages = max(len(r) + 1 for r in routes) + (release is not None)
    rounds = -(-np.asarray(member_counts) // np.asarray(slot_counts))
    cap = int((max_steps + 1) * stages * rounds.max() + 1)
    zeros = jnp.zeros((batch,), jnp.int32)
    start0 = (idx0 // n_routes).astype(jnp.int32)
    carry = dict(
        idx=idx0.astype(jnp.int32),
        y=z0[start0],
        state=jax.vmap(init)(z0[start0]),
        stage=first_stage[idx0 % n_routes].astype(jnp.int32),
        before=zeros,  # steps of the earlier stages of each slot's route
        saved_y=jnp.full((batch, p), jnp.nan, dtype),  # where a route stood before its release
        saved_cost=jnp.full((batch,), jnp.inf, dtype),
        saved_code=zeros,
        live=jnp.asarray(pos0) < end[group],
        nxt=jnp.asarray(first + np.asarray(slot_counts), jnp.int32),
        out_z=jnp.full((n_members, p), jnp.nan, dtype),
        out_cost=jnp.full((n_members,), jnp.nan, dtype),
        out_code=jnp.full((n_members,), MAX_STEPS, jnp.int32),
        out_steps=jnp.zeros((n_members,), jnp.int32),
        it=jnp.asarray(0, jnp.int32),
    )

    def cond(c):
        return (c["it"] < cap) & jnp.any(c["live"])

    def body(c):
        live, stage, idx = c["live"], c["stage"], c["idx"]
        start, route = idx // n_routes, idx % n_routes
        gain = gain_of[stage] if continued else None
        cost, g, H = lin(c["state"].y_eval, start, gain)
        tol = jnp.where(gain_of[stage] > 0, jnp.maximum(rtol[start], STAGE_RTOL), rtol[start])
        y, state = jax.vmap(step)(c["y"], c["state"], (0.5 * cost, g, H), tol)
        done, result = jax.vmap(terminate)(y, state)
        steps = c["before"] + state.num_steps
        diverged = done & (result == optx.RESULTS.nonlinear_divergence)
        converged = done & ~diverged
        capped = ~done & (state.num_steps >= max_steps)
        ended = live & (done | capped)
        code = jnp.where(converged, CONVERGED, jnp.where(diverged, NONFINITE, MAX_STEPS))
        cost_now = jnp.where(diverged, cost, 2.0 * state.f_info.f)
        # a stage that ended hands its point to the next stage of its route
        in_release = stage == release_stage
        advance = ended & ~diverged & ~in_release & (stage < last_stage[route])
        route_end = ended & ~advance
        edge = trapped(y, start)
        go_release = route_end & ~diverged & ~in_release & jnp.any(edge, axis=1)
        finished = route_end & ~go_release
        # a released route ends at the better of its two ends
        keep = in_release & ~(jnp.isfinite(cost_now) & (cost_now < c["saved_cost"]))
        final_z = jnp.where(keep[:, None], c["saved_y"], y)
        final_cost = jnp.where(keep, c["saved_cost"], cost_now)
        final_code = jnp.where(keep, c["saved_code"], code)
        target = jnp.where(finished, idx, n_members)  # out of range: dropped
        out_z = c["out_z"].at[target].set(final_z, mode="drop")
        out_cost = c["out_cost"].at[target].set(final_cost, mode="drop")
        out_code = c["out_code"].at[target].set(final_code, mode="drop")
        out_steps = c["out_steps"].at[target].set(steps, mode="drop")
        # the freed slots take the next members of their group
        onehot = (group[:, None] == np.arange(n_groups)[None, :]) & finished[:, None]
        rank = jnp.cumsum(onehot, axis=0)[jnp.arange(batch), group] - 1
        new_pos = c["nxt"][group] + rank
        load = finished & (new_pos < end[group])
        nxt = jnp.minimum(c["nxt"] + jnp.sum(onehot, axis=0), end).astype(jnp.int32)
        new_idx = order[jnp.where(load, new_pos, 0)]
        released = y if release is None else jnp.where(edge, release_to[start], y)
        y_new = jnp.where(
            load[:, None], z0[new_idx // n_routes], jnp.where(go_release[:, None], released, y)
        )
        renew = load | advance | go_release
        stage_new = jnp.where(
            load,
            first_stage[new_idx % n_routes],
            jnp.where(advance, stage + 1, jnp.where(go_release, release_stage, stage)),
        )
        return dict(
            idx=jnp.where(load, new_idx, idx).astype(jnp.int32),
            y=where(renew, y_new, y),
            state=where(renew, jax.vmap(init)(y_new), state),
            stage=stage_new.astype(jnp.int32),
            before=jnp.where(load, 0, jnp.where(advance | go_release, steps, c["before"])),
            saved_y=jnp.where(go_release[:, None], y, c["saved_y"]),
            saved_cost=jnp.where(go_release, cost_now, jnp.where(load, jnp.inf, c["saved_cost"])),
            saved_code=jnp.where(go_release, code, c["saved_code"]),
            live=jnp.where(finished, load, live),
            nxt=nxt,
            out_z=out_z,
            out_cost=out_cost,
            out_code=out_code,
            out_steps=out_steps,
            it=c["it"] + 1,
        )

    c = lax.while_loop(cond, body, carry)
    # each start's best route
    cost = c["out_cost"].reshape(n_starts, n_routes)
    best = jnp.argmin(jnp.where(jnp.isfinite(cost), cost, jnp.inf), axis=1)
    rows = jnp.arange(n_starts)
    pick = lambda a: a.reshape((n_starts, n_routes) + a.shape[1:])[rows, best]  # noqa: E731
    steps = c["out_steps"].reshape(n_starts, n_routes).sum(axis=1)
    return pick(c["out_z"]), pick(c["out_cost"]), pick(c["out_code"]), steps, c["it"]


# ---- jobs: (problem, starts, data) sharing one compiled solve ------------------------------------


def _problem_key(problem: Problem) -> tuple:
    return (
        *problem.structure_key,
        problem.transform.kinds,
        problem.transform.style,
        problem.simulator,
        problem.sim_options,
    )


def _groups(problems: Sequence[Problem], counts: Sequence[int]):
    """Consecutive members of the same structure: ((problem, count), …)."""
    out: list[list] = []
    for prob, c in zip(problems, counts, strict=True):
        if out and _problem_key(out[-1][0]) == _problem_key(prob):
            out[-1][1] += c
        else:
            out.append([prob, c])
    return tuple((p, c) for p, c in out)


# ---- variants of different shapes in one compiled solve ---------------------------------------


def _paddable(problems: Sequence[Problem], solver) -> bool:
    """Whether variants of different sizes can share one compiled solve: jaxbox's
    Levenberg–Marquardt on the exact simulator, measuring the same states, with as many
    initial-state segments."""
    return (
        (solver is None or isinstance(solver, LevenbergMarquardt))
        and all(p.simulator == "exact" for p in problems)
        and len({(p.output_states, p.model.segments) for p in problems}) == 1
    )


def _same_data(datas) -> bool:
    """Whether every job has the very same arrays (``(t, u, y, w)``: one dataset, several
    models)."""
    first = datas[0]
    return all(
        all(
            np.shape(a) == np.shape(b) and np.array_equal(a, b)
            for a, b in zip(d, first, strict=True)
        )
        for d in datas[1:]
    )


#: a bucketed batch (``solve_jobs(bucket=True)``) rounds each size up to a multiple of these
#: (free and fixed parameters, states, input columns, edges, heat sources, factors per
#: product) and its starts up to a power of two of at least ``starts``
BUCKETS = dict(free=8, fixed=4, states=2, inputs=4, edges=8, sources=8, factors=2, starts=128)


#: the sizes a bucketed batch can be asked to pad to at least (``solve_jobs(bucket={...})``)
SIZES = ("free", "fixed", "states", "inputs", "edges", "sources", "factors")


def _whole(value, least: int) -> bool:
    """Whether ``value`` is a whole number (not a bool) of at least ``least``."""
    return not isinstance(value, bool) and isinstance(value, int | np.integer) and value >= least


def _least(bucket) -> list[dict[str, int]]:
    """The least sizes of ``solve_jobs(bucket=...)``, as a list of candidates: ``[{}]`` for
    ``True`` or ``False``, one for a mapping, each of a sequence of mappings; their keys checked
    against :data:`SIZES`, their values whole numbers of at least 0."""
    if isinstance(bucket, bool) or bucket is None:
        return [{}]
    several = not isinstance(bucket, Mapping)
    if several and not (
        isinstance(bucket, Sequence) and bucket and all(isinstance(b, Mapping) for b in bucket)
    ):
        raise FitError(
            "bucket must be True, False, a mapping of sizes or a sequence of such mappings, "
            f"got {bucket!r}"
        )
    out = []
    for sizes in bucket if several else [bucket]:
        unknown = sorted(set(sizes) - set(SIZES))
        if unknown:
            raise FitError(
                f"bucket sizes {', '.join(map(repr, unknown))} are not sizes of a batch; "
                f"use any of {', '.join(SIZES)}"
            )
        least = {}
        for name, value in sizes.items():
            if not _whole(value, 0):
                raise FitError(f"bucket size {name!r} must be a whole number ≥ 0, got {value!r}")
            least[name] = int(value)
        out.append(least)
    return out


def _bucketed_sizes(problems, z0s, members, datas) -> dict[str, int]:
    """The sizes a bucketed batch of these jobs pads to on its own (:data:`BUCKETS`)."""
    each = [p.model.array_sizes() for p in problems]
    own = {k: max(e[k] for e in each) for k in ("edges", "sources", "factors")}
    own.update(
        free=max(z.shape[1] for z in z0s),
        fixed=max(m[0].shape[1] for m in members),
        states=max(len(p.model.states) for p in problems),
        inputs=_input_layout(problems, datas, True)[0]["inputs"],
    )
    return {k: _round_up(v, BUCKETS.get(k, 1)) for k, v in own.items()}


def _holding(candidates: list[dict[str, int]], own: dict[str, int]) -> dict[str, int]:
    """The first of ``candidates`` whose sizes (rounded up) hold a batch of sizes ``own``; the
    last where none does (the batch then pads to the larger of each)."""
    for least in candidates:
        if all(v <= _round_up(least.get(k, 0), BUCKETS.get(k, 1)) for k, v in own.items()):
            return least
    return candidates[-1]


def _round_up(n: int, step: int) -> int:
    return step * max(1, -(-n // step))


def _bucket_starts(n: int) -> int:
    """Starts of a bucketed batch: a power of two, at least ``BUCKETS["starts"]``."""
    return max(BUCKETS["starts"], 1 << max(0, int(n) - 1).bit_length())


def bucket_samples(n: int) -> int:
    """Samples of a batch whose data are padded (:func:`solve_jobs`): ``n`` rounded up to a
    sixteenth of an octave (at most 6.25 % more above 256 samples; a multiple of 16 below), so
    that records of neighbouring lengths share one compiled solve."""
    n = int(n)
    if n <= 256:
        return _round_up(n, 16)
    return _round_up(n, 1 << (n.bit_length() - 5))


def _pad_samples(data, n: int):
    """``(t, u, y, w)`` [N, …] extended to ``n`` samples: the times go on at the data's step,
    the inputs and outputs hold their last values, the weights are 0. The cost, ``Jᵀr`` and
    ``JᵀJ`` are those of the data to rounding (a sample of weight 0 adds zeros, though the sums
    run in other blocks, and the observer of the continuation does not pull where the weight
    is 0); the padded steps come after the last sample, so no state before it depends on
    them."""
    t, u, y, w = data
    k = int(n) - len(t)
    if k <= 0:
        return data
    w = np.concatenate([w, np.zeros((k, *w.shape[1:]))], axis=0)
    return extend_times(t, n), hold_rows(u, n), hold_rows(y, n), w


def _input_layout(problems, datas, bucket: bool = False, least: int = 0):
    """One input layout for variants with different inputs: the union of their inputs by name
    when they share the data (``t``, ``y``, ``w`` and every input of the same name), else each
    job's own inputs padded with zero columns (``bucket``: their number, at least ``least``,
    rounded up, see :data:`BUCKETS`). Returns ``(layout, datas)``: ``layout`` maps a problem to
    the columns of its inputs."""
    step = BUCKETS["inputs"] if bucket else 1
    shared = _same_data([(d[0], d[2], d[3]) for d in datas])
    columns: dict[str, np.ndarray] = {}
    for prob, d in zip(problems, datas, strict=True):
        for j, name in enumerate(prob.model.inputs):
            col = d[1][:, j]
            if name in columns and not np.array_equal(columns[name], col, equal_nan=True):
                shared = False
            columns.setdefault(name, col)
    if shared:
        names = list(columns)
        u = np.stack([columns[n] for n in names], axis=1) if names else datas[0][1]
        m = _round_up(max(u.shape[1], least), step)
        u = np.pad(u, ((0, 0), (0, m - u.shape[1])))
        layout = {"union": tuple(names), "inputs": m}
        return layout, [(d[0], u, d[2], d[3]) for d in datas]
    m = _round_up(max(least, *(d[1].shape[1] for d in datas)), step)
    padded = [(d[0], np.pad(d[1], ((0, 0), (0, m - d[1].shape[1]))), d[2], d[3]) for d in datas]
    return {"union": None, "inputs": m}, padded


def _pad_members(problems, z0s, members, bucket: bool = False, least=None):
    """Starts and per-member arrays padded to the widest variant (``bucket``: to its width, at
    least ``least["free"]`` and ``least["fixed"]``, rounded up, see :data:`BUCKETS`): inert
    coordinates (zero, in bounds [0, 1], scale 1) that no residual depends on, so the solver
    leaves them where they are (their column of J is zero: see
    :class:`~jaxbox.fit.LevenbergMarquardt`)."""
    least = least or {}
    p = max(z.shape[1] for z in z0s)
    q = max(m[0].shape[1] for m in members)
    if bucket:
        p = _round_up(max(p, least.get("free", 0)), BUCKETS["free"])
        q = _round_up(max(q, least.get("fixed", 0)), BUCKETS["fixed"])

    def pad(a, width, value):
        return np.pad(a, ((0, 0), (0, width - a.shape[1])), constant_values=value)

    z0s = [pad(z, p, 0.0) for z in z0s]
    members = [
        (pad(f, q, 0.0), pad(lo, p, 0.0), pad(hi, p, 1.0), pad(sc, p, 1.0), dt)
        for f, lo, hi, sc, dt in members
    ]
    return z0s, members


def _anchors(prob: Problem) -> np.ndarray:
    """What a coordinate trapped on its bound is released towards (internal coordinates [p]):
    the problem's guess (the naming convention's, the parent case's or the caller's), the
    middle of the bounds where the guess itself lies within :data:`EDGE` of one.

    A trapped coordinate is released halfway from its start value to its anchor. Measured on
    the 22 models of ``benchmarks/convergence.py`` (64 starts each, the defaults), the starts
    that reach the best cost: 782 released to their start values, 831 to the guess, 815
    halfway; at least half of the starts on 14, 14 and 15 of the models. On the synthetic
    ``ZonWalIntInf`` building of the tests (12 starts, plain output error with the release,
    three seeds): 12, 11, 10 at best released to their start values, 9, 11, 9 to the guess,
    11, 12, 10 halfway."""
    tr = prob.transform
    guess = np.asarray([prob.guess_dict[k] for k in prob.free], dtype=float)
    z = np.where(np.isfinite(guess), tr.to_internal(guess), 0.0)
    pos = tr.relative_position(guess)
    return np.where(two_sided(tr.kinds) & _near_edge(pos), 0.0, z)


def _near_edge(pos):
    """Positions in the bounds (0 … 1, NumPy or JAX) within :data:`EDGE` of either bound."""
    return (pos < EDGE) | (pos > 1.0 - EDGE)


def _pad_spec(prob: Problem, layout) -> tuple:
    """Static padding of one variant: ``(free, fixed, states, its input columns, states of the
    batch, inputs of the batch)``."""
    names = layout["union"]
    inputs = tuple(range(len(prob.model.inputs)))
    if names is not None:
        inputs = tuple(names.index(n) for n in prob.model.inputs)
    n = len(prob.model.states)
    return (len(prob.free), len(prob.fixed), n, inputs, layout["states"], layout["inputs"])


def _padded_matrices(prob: Problem, spec, args):
    """``prob.matrices`` (and their tangents) of a batch, padded to the batch's widest variant:
    extra states that stay at zero (Φ = I, no input, x0 = 0), the inputs at the layout's
    columns, zero tangents along the padding coordinates."""
    n_free, n_fixed, n, inputs, n_max, m_max = spec
    Z, fixed, lo, hi, sc, dt = args
    own = (Z[:, :n_free], fixed[:, :n_fixed], lo[:, :n_free], hi[:, :n_free], sc[:, :n_free], dt)
    (Phi, G0, G1, x0), (dPhi, dG0, dG1, dx0) = jax.vmap(value_and_jacfwd(prob.matrices))(*own)
    dq = Z.shape[1] - n_free
    P = np.zeros((len(inputs), m_max))
    P[np.arange(len(inputs)), list(inputs)] = 1.0

    def states(a, axes, tangent):
        """Pad the state axes ``axes`` to ``n_max`` (and the tangent axis to the batch's)."""
        width = [(0, 0)] * a.ndim
        for ax in axes:
            width[ax] = (0, n_max - n)
        if tangent:
            width[-1] = (0, dq)
        return jnp.pad(a, width)

    eye = np.zeros((n_max, n_max))
    eye[np.arange(n, n_max), np.arange(n, n_max)] = 1.0
    Phi = states(Phi, (1, 2), False) + eye
    G0, G1 = (states(jnp.einsum("bnm,mk->bnk", g, P), (1,), False) for g in (G0, G1))
    dG0, dG1 = (states(jnp.einsum("bnmq,mk->bnkq", g, P), (1,), True) for g in (dG0, dG1))
    return (
        (Phi, G0, G1, states(x0, (x0.ndim - 1,), False)),
        (states(dPhi, (1, 2), True), dG0, dG1, states(dx0, (dx0.ndim - 2,), True)),
    )


#: the arrays of a network in array form, in the order the compiled solve takes them
_RC_KEYS = ("R", "scale", "fk", "fa", "fb", "KG", "KH", "sk", "sa", "sb", "KS", "C", "T0", "pad")


def _array_form(problems) -> bool:
    """Whether the networks of ``problems`` can go into one program in array form: one
    transform style, no node held at a constant temperature."""
    return len({p.transform.style for p in problems}) == 1 and not any(
        node.constant for p in problems for node in p.model.network.nodes
    )


def _rc_members(
    problems, counts, layout, width: int, fixed_width: int, bucket: bool = False, least=None
):
    """Per member (start) ``(kinds [B, p], *arrays)`` of every variant's network in array form
    (:meth:`~jaxbox.models.RCModel.rc_arrays`), padded to the batch's largest (``bucket``: its
    sizes, at least those of ``least``, rounded up, see :data:`BUCKETS`), and the sizes
    (``edges``, ``sources``, ``factors``, ``states``); ``None`` when a network has no array
    form (a constant node)."""
    from ..models._network import ModelError

    if not _array_form(problems):
        return None
    least = least or {}
    names = layout["union"]
    each = [p.model.array_sizes() for p in problems]
    sizes = {k: max(e[k] for e in each) for k in each[0]}
    if bucket:
        sizes = {k: _round_up(max(v, least.get(k, 0)), BUCKETS.get(k, 1)) for k, v in sizes.items()}
    sizes["states"] = layout["states"]
    parts = []
    for prob, c in zip(problems, counts, strict=True):
        free = list(prob.free) + [f"\0p{i}" for i in range(width - len(prob.free))]
        fixed = [n for n, _ in prob.fixed]
        fixed += [f"\0q{i}" for i in range(fixed_width - len(fixed))]
        inputs = list(prob.model.inputs) if names is None else list(names)
        inputs += [f"\0u{i}" for i in range(layout["inputs"] - len(inputs))]
        try:
            arrays = prob.model.rc_arrays(free + fixed + ["1", "0"], inputs=inputs, **sizes)
        except ModelError:
            return None
        kinds = np.asarray(list(prob.transform.kinds) + [1] * (width - len(prob.free)))
        one = (kinds, *(arrays[k] for k in _RC_KEYS))
        parts.append(tuple(np.broadcast_to(a, (c, *np.shape(a))) for a in one))
    return tuple(np.concatenate(p, axis=0) for p in zip(*parts, strict=True)), sizes


def _rc_matrices(style: str):
    """Discrete matrices of one member from its network in array form: ``(z, fixed, lo, hi,
    sc, dt, kinds, *arrays) -> (Φ, Γ0, Γ1, x0)`` (see :meth:`Problem.matrices`)."""
    from ..models._network import rc_from_arrays
    from ..simulate._exact import discretize_foh_rc
    from ._transforms import to_physical_coded

    def matrices(z, fixed, lo, hi, sc, dt, kinds, *arrays):
        p = to_physical_coded(z, lo, hi, sc, kinds, style)
        v = jnp.concatenate([p, fixed, jnp.asarray([1.0, 0.0], dtype=p.dtype)])
        A, B, caps, x0 = rc_from_arrays(v, dict(zip(_RC_KEYS, arrays, strict=True)))
        return (*discretize_foh_rc(A, B, caps, dt), x0)

    return matrices


def _build(
    groups,
    slot_counts,
    max_steps: int,
    solver,
    pads=None,
    rc: bool = False,
    homotopy=(),
    release: bool = True,
):
    if not isinstance(solver, LevenbergMarquardt):
        return _build_generic(groups, max_steps, solver)
    exact = all(p.simulator == "exact" for p, _ in groups)
    if not exact and len(groups) > 1:
        raise FitError("model variants can only be batched with the exact simulator")
    if len({p.output_states for p, _ in groups}) > 1:
        raise FitError("model variants batched together must measure the same states")
    style = groups[0][0].transform.style

    def solve(
        z0, bounded, routed, active, anchor, rtol, fixed, lo, hi, sc, dt, t, u, y, w, *structure
    ):
        per_member = u.shape[1] != 1

        def lin(Z, idx, gain):
            members = tuple(a[idx] for a in (fixed, lo, hi, sc, dt))
            data = tuple(a[:, idx] if per_member else a for a in (t, u, y, w))
            if not exact:
                return groups[0][0].normal_equations(Z, members, data)
            if rc:  # every variant through one program: its network in array form
                args = (Z, *members, *(a[idx] for a in structure))
                mats = _rc_matrices(groups[0][0].transform.style)
                tt, uu, yy, ww = data
                prim, tang = jax.vmap(value_and_jacfwd(mats))(*args)
                return normal_equations_auto(
                    prim, tang, groups[0][0].output_states, uu, yy, ww, t=tt, gain=gain
                )
            prim, tang, start = [], [], 0
            for k, ((prob, _), count) in enumerate(zip(groups, slot_counts, strict=True)):
                sl = slice(start, start + count)
                start += count
                args = (Z[sl],) + tuple(a[sl] for a in members)
                if pads is None:
                    pm, pt = jax.vmap(value_and_jacfwd(prob.matrices))(*args)
                    prim.append(pm)
                    tang.append(pt)
                else:
                    pm, pt = _padded_matrices(prob, pads[k], args)
                    prim.append(pm)
                    tang.append(pt)
            cat = lambda parts: tuple(  # noqa: E731
                jnp.concatenate(x, axis=0) if len(x) > 1 else x[0] for x in zip(*parts, strict=True)
            )
            tt, uu, yy, ww = data
            return normal_equations_auto(
                cat(prim), cat(tang), groups[0][0].output_states, uu, yy, ww, t=tt, gain=gain
            )

        return _multistart(
            solver,
            lin,
            z0,
            max_steps=max_steps,
            start_counts=tuple(c for _, c in groups),
            slot_counts=slot_counts,
            active=active,
            rtol=rtol,
            # the continuation needs the observer of the exact route
            routes=((), homotopy) if homotopy and exact else ((),),
            release=(bounded, lambda Z: position_in_bounds(style, Z), anchor) if release else None,
            routed=routed,
        )

    return jit(solve, lean=True)


def _build_generic(groups, max_steps: int, solver):
    """Any other optimistix least-squares solver, one ``optx.least_squares`` per start under
    ``vmap``: the Jacobian by forward-mode autodiff through the problem's simulator."""
    if len(groups) > 1:
        raise FitError(
            "model variants can only be batched with jaxbox.LevenbergMarquardt; fit them one "
            "by one with another solver"
        )
    prob = groups[0][0]

    def solve(z0, bounded, routed, active, anchor, rtol, fixed, lo, hi, sc, dt, t, u, y, w):
        per_member = u.shape[1] != 1

        def one(z, f, a, b, c, tt, uu, yy, ww):
            def residuals(zz, _):
                p = prob.transform.to_physical(zz, a, b, c)
                return ((prob.simulate(p, f, tt, uu) - yy) * ww).ravel()

            sol = optx.least_squares(residuals, solver, z, max_steps=max_steps, throw=False)
            r = residuals(sol.value, None)
            steps = sol.stats["num_steps"]
            ok = sol.result == optx.RESULTS.successful
            code = jnp.where(ok, CONVERGED, jnp.where(steps >= max_steps, MAX_STEPS, NONFINITE))
            return sol.value, r @ r, code.astype(jnp.int32), steps

        d_axis = 1 if per_member else None
        if not per_member:
            t, u, y, w = (a[:, 0] for a in (t, u, y, w))
        axes = (0, 0, 0, 0, 0, d_axis, d_axis, d_axis, d_axis)
        return jax.vmap(one, in_axes=axes)(z0, fixed, lo, hi, sc, t, u, y, w)

    return jit(solve)


def parallel_parts(n_starts: int) -> int:
    """Into how many parts a batch of ``n_starts`` is dealt (a bucketed batch, or the starts of
    one problem), the parts run side by side by threads on one executable: on a CPU one per
    usable core (:func:`_usable_cores`; ``JAXBOX_THREADS`` sets the number; each part keeps at
    least 8 starts), on an accelerator one. XLA runs one batched solve on about one core; each
    start's result does not depend on the part it ran in."""
    if jax.default_backend() != "cpu":
        return 1
    env = os.environ.get("JAXBOX_THREADS", "").strip()
    if env:
        try:
            threads = max(1, int(env))
        except ValueError:
            raise FitError(f"JAXBOX_THREADS must be a whole number, got {env!r}") from None
    else:
        threads = _usable_cores()
    return max(1, min(threads, n_starts // 8))


def _usable_cores(cpu_max: str = "/sys/fs/cgroup/cpu.max") -> int:
    """The cores this process may use: those of its affinity set, no more than its container's
    CPU quota (cgroup v2 ``cpu.max``, ``"200000 100000"``: two cores) where one is set."""
    if hasattr(os, "sched_getaffinity"):
        cores = len(os.sched_getaffinity(0))
    else:
        cores = os.cpu_count() or 1
    try:
        quota, period = Path(cpu_max).read_text().split()[:2]
        if quota != "max" and float(period) > 0:
            cores = min(cores, int(float(quota) / float(period)))
    except (OSError, ValueError):
        pass
    return max(1, cores)


def _run_parts(compiled, calls):
    """``compiled(*args)`` for each of ``calls``, side by side (the executable releases the
    interpreter while it runs), in order."""
    if len(calls) == 1:
        return [jax.block_until_ready(compiled(*calls[0]))]
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(len(calls)) as pool:
        return list(pool.map(lambda a: jax.block_until_ready(compiled(*a)), calls))


def _starts_per_job(value, n_jobs: int, name: str, least: int) -> list[int | None]:
    """A per-job count of starts of :func:`solve_jobs` (one value, or one per job): ``None``
    or a whole number from ``least``, refused by ``name`` otherwise."""
    values = list(value) if isinstance(value, Sequence) else [value] * n_jobs
    if len(values) != n_jobs:
        raise FitError(f"{name} needs one value per job ({n_jobs}), got {len(values)}")
    for v in values:
        if v is not None and not _whole(v, least):
            raise FitError(
                f"{name} must be None or a whole number of starts from {least}, got {v!r}"
            )
    return [None if v is None else int(v) for v in values]


def check_continued(value, n_jobs: int) -> list[int | None]:
    """``continued=`` of :func:`solve_jobs` as one value per job: ``None`` or a whole number
    from 0."""
    return _starts_per_job(value, n_jobs, "continued", 0)


def check_polish(value, n_jobs: int) -> list[int | None]:
    """``polish=`` of :func:`solve_jobs` as one value per job: ``None`` or a whole number from
    1."""
    return _starts_per_job(value, n_jobs, "polish", 1)


def _polished(cost, counts, polish) -> np.ndarray:
    """Which starts a polishing pass takes on: the ``k`` of lowest finite cost of each job
    with ``polish`` ``k`` (ties: the earlier start)."""
    chosen = np.zeros(len(cost), bool)
    first = 0
    for c, k in zip(counts, polish, strict=True):
        if k is not None:
            own = cost[first : first + c]
            finite = np.flatnonzero(np.isfinite(own))
            best = finite[np.argsort(own[finite], kind="stable")[:k]]
            chosen[first + best] = True
        first += c
    return chosen


def solve_jobs(
    jobs: Sequence[tuple[Problem, Float[np.ndarray, "starts free"], tuple]],
    *,
    max_steps: int = DEFAULT_MAX_STEPS,
    rtol: float = 1e-6,
    atol: float = 1e-16,
    slots: int | None = None,
    solver: optx.AbstractLeastSquaresSolver | None = None,
    homotopy: Sequence[float] = DEFAULT_HOMOTOPY,
    release: bool = True,
    bucket: bool | Mapping[str, int] = False,
    continued: Sequence[int | None] | int | None = None,
    polish: Sequence[int | None] | int | None = None,
    compile_only: bool = False,
) -> dict:
    """Run a least-squares solver for several jobs in one compiled, batched call.

    A job is ``(problem, starts [S, p] physical, arrays)`` with ``arrays`` from
    :func:`~jaxbox.fit.problem_arrays`. Every job must have the same number of free parameters,
    samples, states, inputs and outputs; jobs may differ in data (buildings, windows), bounds,
    fixed values and, with the exact simulator, in model structure (variants of the same shape).
    With jaxbox's solver on the exact simulator, records of different lengths batch together:
    each is padded at its end with samples of weight 0 to :func:`bucket_samples` of the longest,
    which changes the results only to rounding (see :func:`_pad_samples`).
    A single job shares its data across its starts. With jaxbox's solver each start is solved
    along two routes, the output-error problem directly and, on the exact simulator, the
    continuation ``homotopy`` (observer gains, see :func:`check_homotopy`; ``()``: none), and a
    route that ends with coordinates on their bounds is retried with them released
    (``release``); the better route is the start's result (see :func:`_multistart`).
    ``continued`` (one per job, or one for all): how many of a job's starts, the first ones,
    take the continuation as well (``None``: all; the others the output-error route alone). It
    is an argument of the compiled program, not part of its key.
    ``polish`` (one per job, or one for all; jaxbox's solver): ``k`` solves every start of the
    job to the looser tolerance :data:`POLISH_RTOL` (or ``rtol`` where that is looser), then
    its ``k`` best starts on to ``rtol``, along the output error from where they ended (a
    second call of the same program); ``None`` (default) every start to ``rtol``. For a job of
    which only the best start counts (a structure search's candidate) it spares the steps that
    bring the other starts from near their optima to the last digits.

    With ``bucket`` (jaxbox's solver on the exact simulator, networks in array form), every
    size of the batch is rounded up (:data:`BUCKETS`: parameters, states, inputs, edges; the
    starts to a power of two, the padding starts never solved) and the starts share one queue
    of slots, so that calls of neighbouring sizes — the steps of a structure search, one job or
    many — run one compiled program instead of one each. The results are those of the call
    without ``bucket``, to rounding. A mapping instead of ``True`` sets sizes to pad to at
    least (any of :data:`SIZES`: ``{"inputs": 12}``, the input columns of the largest call to
    come; the ``sizes`` an earlier call returned, so that this one reuses its compiled
    program). A sequence of such mappings (ascending) pads the batch to the first that holds
    it (each of the batch's own sizes, rounded up, within the mapping's), else to its own sizes
    and the last's: ``[sizes, larger]`` runs an earlier batch's program, or the larger one
    (compiled ahead, see ``compile_only``) once the batch outgrows it. On a CPU the
    starts of a bucketed batch, or of a batch of one problem (one structure) with jaxbox's
    solver, are dealt to :func:`parallel_parts` that run side by side.

    Returns a dict with per member (all starts of all jobs, in order): ``job`` [B], ``z``, ``p``
    [B, p], ``code`` [B], ``steps``, ``cost``; and ``compile_s``, ``fit_s`` [s] and
    ``memory_bytes``, the compiled solve's arguments, outputs and scratch memory (-1 if the
    backend does not report it); ``slots``, the starts iterated together in each of ``parts``
    queues that run side by side; ``iterations``, each part's iterations (jaxbox's solver: each
    advances every slot by one step, so ``slots × Σ iterations`` steps are computed for
    ``Σ steps`` of use); ``sizes``, the sizes a bucketed batch was padded to (a mapping of
    :data:`SIZES`; ``None`` where the batch was not bucketed).

    ``compile_only``: build the batch's compiled program (kept for the calls to come) without
    solving; returns ``compile_s``, ``built`` (whether this call compiled it) and ``sizes``.
    """
    if not jobs:
        raise FitError("no job to solve")
    homotopy = check_homotopy(homotopy)
    continued = check_continued(continued, len(jobs))
    polish = check_polish(polish, len(jobs))
    problems, z0s, counts, members, datas, edges, anchors = [], [], [], [], [], [], []
    for prob, starts, arrays in jobs:
        starts = np.atleast_2d(np.asarray(starts, dtype=float))
        tr = prob.transform
        z0 = tr.to_internal(starts)
        # a start that is not finite is passed through: it fails inside the batch and is reported
        z0 = np.where(np.isfinite(starts), z0, np.nan)
        s = len(z0)
        t, u, y, sqrt_w = arrays
        fixed = np.asarray([v for _, v in prob.fixed], dtype=float)
        members.append(
            (
                np.broadcast_to(fixed, (s, len(fixed))),
                np.broadcast_to(tr.lower, (s, len(tr.lower))),
                np.broadcast_to(tr.upper, (s, len(tr.upper))),
                np.broadcast_to(tr.scale, (s, len(tr.scale))),
                np.full((s,), float(t[1] - t[0])),
            )
        )
        w = np.broadcast_to(np.asarray(sqrt_w, dtype=float), np.shape(y))
        datas.append((np.asarray(t, float), np.asarray(u, float), np.asarray(y, float), w))
        problems.append(prob)
        z0s.append(z0)
        edges.append(np.broadcast_to(two_sided(tr.kinds), z0.shape))
        anchors.append(np.broadcast_to(_anchors(prob), z0.shape))
        counts.append(s)
    variants = len({_problem_key(p) for p in problems}) > 1
    paddable = _paddable(problems, solver)
    candidates = _least(bucket)
    bucket = bool(bucket) and paddable and _array_form(problems)
    least = candidates[0]
    if bucket and len(candidates) > 1:
        least = _holding(candidates, _bucketed_sizes(problems, z0s, members, datas))
    lengths = {len(d[0]) for d in datas}
    if paddable and len(lengths) > 1:
        # records of different lengths in one batch: padded at the end to the bucket of the
        # longest, so that batches of neighbouring lengths share a compiled solve (a record
        # that is padded sums its residuals in other blocks: its result changes to rounding)
        datas = [_pad_samples(d, bucket_samples(max(lengths))) for d in datas]
    if (variants or bucket) and paddable:
        layout, datas = _input_layout(problems, datas, bucket, least.get("inputs", 0))
        n_states = max(len(p.model.states) for p in problems)
        if bucket:
            n_states = _round_up(max(n_states, least.get("states", 0)), BUCKETS["states"])
        layout["states"] = n_states
        z0s, members = _pad_members(problems, z0s, members, bucket, least)
    else:
        layout = None
    shapes = {(np.shape(z)[1], *(np.shape(a) for a in d)) for z, d in zip(z0s, datas, strict=True)}
    if len(shapes) > 1:
        raise FitError(
            "jobs batched together need the same number of free parameters and data of the same "
            f"shape (samples, inputs, outputs); got {sorted(shapes)}"
        )
    z0 = np.concatenate(z0s, axis=0)
    # the coordinates a route may release from a bound (none of a variant's padding)
    bounded = np.concatenate(
        [np.pad(e, ((0, 0), (0, z0.shape[1] - e.shape[1]))) for e in edges], axis=0
    )
    anchor = np.concatenate(
        [np.pad(a, ((0, 0), (0, z0.shape[1] - a.shape[1]))) for a in anchors], axis=0
    )
    # the starts that take every route
    routed = np.concatenate(
        [np.arange(c) < (c if k is None else k) for c, k in zip(counts, continued, strict=True)]
    )
    member_arrays = tuple(np.concatenate(parts, axis=0) for parts in zip(*members, strict=True))
    if solver is None:
        solver = LevenbergMarquardt(rtol=rtol, atol=atol)
    elif not isinstance(solver, optx.AbstractLeastSquaresSolver | optx.AbstractMinimiser):
        raise FitError(
            f"solver must be an optimistix least-squares solver or minimiser (e.g. "
            f"jaxbox.LevenbergMarquardt(), optimistix.Dogleg(rtol, atol)), got {solver!r}"
        )
    fused = isinstance(solver, LevenbergMarquardt)
    if any(k is not None for k in polish) and not fused:
        raise FitError("polish needs jaxbox.LevenbergMarquardt as the solver")
    # each start's tolerance (an argument of the program: the solver's own is not in its key)
    tight = solver.rtol if fused else rtol
    loose = max(POLISH_RTOL, tight)
    tolerance = np.concatenate(
        [np.full(c, tight if k is None else loose) for c, k in zip(counts, polish, strict=True)]
    )
    if len(jobs) == 1 or _same_data(datas):
        data = tuple(a[:, None] for a in datas[0])  # shared by every start: [N, 1, …]
    else:
        data = tuple(
            np.concatenate(
                [np.repeat(d[k][:, None], c, axis=1) for d, c in zip(datas, counts, strict=True)],
                axis=1,
            )
            for k in range(4)
        )
    groups = _groups(problems, counts)
    pads = None if layout is None else tuple(_pad_spec(p, layout) for p, _ in groups)
    rc = sizes = None
    if layout is not None:
        rc = _rc_members(
            problems, counts, layout, z0.shape[1], member_arrays[0].shape[1], bucket, least
        )
    if rc is not None:
        rc, network = rc
        sizes = dict(
            free=z0.shape[1], fixed=member_arrays[0].shape[1], inputs=layout["inputs"], **network
        )
    n_real = len(z0)
    bucket = bucket and rc is not None
    parts = [np.arange(n_real)]
    # the starts dealt to parts that run side by side, each in one queue of slots: a bucketed
    # batch, or one group of starts with jaxbox's solver (one program serves every part)
    n_parts = parallel_parts(n_real) if bucket or (len(groups) == 1 and paddable) else 1
    split = bucket or n_parts > 1
    if split:
        parts = [np.arange(j, n_real, n_parts) for j in range(n_parts)]
        size = _bucket_starts(len(parts[0])) if bucket else len(parts[0])
        groups = ((groups[0][0], size),)
    # data shared by every start go to the device once, for every part
    shared = [jax.device_put(np.asarray(a, float)) if a.shape[1] == 1 else None for a in data]

    def arguments(rows, polishing=None):
        """The compiled solve's arguments for the starts ``rows`` (split: padded with copies of
        the last, never solved); ``polishing``: ``(z [S, p], chosen [S])``, the starts to
        polish from ``z``."""
        n_rows = len(rows)
        if split:
            rows = rows[np.minimum(np.arange(size), n_rows - 1)]
        if polishing is None:
            z_in, edge, both, on, tol = z0, bounded, routed, np.ones(len(z0), bool), tolerance
        else:  # the chosen starts from where they ended, along the output error alone, unreleased
            z_in, on = polishing
            edge, both = np.zeros_like(bounded), np.zeros(len(z0), bool)
            tol = np.full(len(z0), tight * POLISH_TIGHTER)
        own = (z_in, edge, both, on, anchor, tol, *member_arrays)
        if split:
            own = tuple(np.asarray(a)[rows] for a in own)
            own[3][n_rows:] = False  # the copies that pad a part: never solved
        put = [
            jax.device_put(np.asarray(a, dtype=bool if k in (1, 2, 3) else float))
            for k, a in enumerate(own)
        ]
        put += [
            d if d is not None else jax.device_put(np.asarray(a[:, rows] if split else a, float))
            for a, d in zip(data, shared, strict=True)
        ]
        if rc is not None:
            put.extend(jax.device_put(np.asarray(a)[rows] if split else np.asarray(a)) for a in rc)
        return tuple(put)

    calls = [arguments(rows) for rows in parts]
    args = calls[0]
    if rc is not None:  # one program for every variant: the key holds no structure
        pads = ("rc", problems[0].transform.style, problems[0].output_states)
    n_total = len(args[0])
    if slots is None:
        narrow = min(n_total, _ACCELERATOR_NARROW)
        n_states = max(len(p.model.states) for p in problems)
        parallel = prefer_parallel(len(data[0]), narrow, n_states, z0.shape[1])
        n_slots = default_slots(n_total, parallel=parallel)
    else:
        n_slots = max(1, int(slots))
    slot_counts = tuple(min(c, max(1, round(n_slots * c / n_total))) for _, c in groups)
    if fused:  # the tolerance is an argument: one program serves every rtol
        solver = eqx.tree_at(lambda s: s.rtol, solver, 0.0)
    key = (
        "fit",
        "bucket" if bucket else ("parts" if split else None),
        tuple((_problem_key(p), c) if rc is None else c for p, c in groups),
        slot_counts,
        solver_key(solver),
        tuple((a.shape, a.dtype) for a in args),
        max_steps,
        pads,
        homotopy,
        bool(release),
    )
    t0 = time.perf_counter()

    def build():
        jitted = _build(
            groups, slot_counts, max_steps, solver, pads, rc is not None, homotopy, release
        )
        return compile_program("fit", key, jitted, args)

    compiled, built = _compiled.cached(key, build)
    compile_s = time.perf_counter() - t0 if built else 0.0
    if compile_only:
        return {"compile_s": compile_s, "built": built, "sizes": sizes if bucket else None}
    try:
        mem = compiled.memory_analysis()
        memory = int(mem.temp_size_in_bytes + mem.argument_size_in_bytes + mem.output_size_in_bytes)
    except Exception:  # not every backend reports it
        memory = -1
    t0 = time.perf_counter()
    outs = _run_parts(compiled, calls)
    z, cost, code, steps = (
        np.empty((n_real, *np.shape(a)[1:]), dtype=np.asarray(a).dtype) for a in outs[0][:4]
    )
    # jaxbox's solver: the iterations of each part's loop (each advances every slot by a step)
    iterations = [int(out[4]) for out in outs if len(out) > 4]
    for rows, out in zip(parts, outs, strict=True):
        for whole, part in zip((z, cost, code, steps), out[:4], strict=True):
            whole[rows] = np.asarray(part)[: len(rows)]
    chosen = _polished(cost, counts, polish)
    if chosen.any():  # the best starts of the polished jobs on to the full tolerance
        picked = np.flatnonzero(chosen)
        if split:
            # side by side as the first pass, at least 8 a part, no more than a part holds
            n_p = max(-(-len(picked) // size), min(len(parts), len(picked) // 8), 1)
            rows_p = [picked[j::n_p] for j in range(n_p)]
        else:
            rows_p = [np.arange(n_real)]
        outs = _run_parts(compiled, [arguments(r, (z, chosen)) for r in rows_p])
        iterations += [int(out[4]) for out in outs if len(out) > 4]
        for rows, out in zip(rows_p, outs, strict=True):
            keep = chosen[rows]
            rows = rows[keep]
            z_p, cost_p, code_p, steps_p = (np.asarray(a)[: len(keep)][keep] for a in out[:4])
            # the polished end, where it is finite (it is never worse than where it began)
            ok = np.isfinite(cost_p) & (cost_p <= cost[rows])
            z[rows] = np.where(ok[:, None], z_p, z[rows])
            cost[rows] = np.where(ok, cost_p, cost[rows])
            code[rows] = np.where(ok, code_p, code[rows])
            steps[rows] = steps[rows] + steps_p
    fit_s = time.perf_counter() - t0
    p_parts, start = [], 0
    width = z.shape[1]
    for prob, c in zip(problems, counts, strict=True):
        sl, k = slice(start, start + c), len(prob.free)
        phys = prob.transform.to_physical(
            np.asarray(z[sl, :k], dtype=float),
            member_arrays[1][sl, :k],
            member_arrays[2][sl, :k],
            member_arrays[3][sl, :k],
        )
        # a padded job (see _pad_members): its padding columns are NaN, result_from drops them
        p_parts.append(np.pad(np.asarray(phys), ((0, 0), (0, width - k)), constant_values=np.nan))
        start += c
    return {
        "job": np.repeat(np.arange(len(jobs)), counts),
        "z": z,
        "p": np.concatenate(p_parts, axis=0),
        "code": np.asarray(code),
        "steps": np.asarray(steps),
        "cost": np.asarray(cost),
        "compile_s": compile_s,
        "fit_s": fit_s,
        "memory_bytes": memory,
        "slots": int(sum(slot_counts)),
        "parts": len(parts),
        "iterations": iterations,
        "sizes": sizes if bucket else None,
    }


def solve_starts(
    problem: Problem,
    starts: np.ndarray,
    arrays,
    *,
    max_steps: int = DEFAULT_MAX_STEPS,
    rtol: float = 1e-6,
    atol: float = 1e-16,
    slots: int | None = None,
    homotopy: Sequence[float] = DEFAULT_HOMOTOPY,
    release: bool = True,
):
    """Run LM from every start (physical values [S, p]) in one compiled, batched call.

    Returns a dict with ``z``, ``p`` [S, p], ``code`` [S] (0 converged, 1 step cap,
    2 non-finite), ``steps``, ``cost`` [S], ``compile_s`` and ``fit_s``.
    """
    out = solve_jobs(
        [(problem, starts, arrays)],
        max_steps=max_steps,
        rtol=rtol,
        atol=atol,
        slots=slots,
        homotopy=homotopy,
        release=release,
    )
    out.pop("job")
    return out


def _status(code: int, cost: float, p: np.ndarray) -> str:
    if not (np.isfinite(cost) and np.all(np.isfinite(p))):
        return "nonfinite"
    return _STATUS.get(int(code), f"failed (code {int(code)})")


def make_starts(problem: Problem, data, starts, seed, concentration) -> np.ndarray:
    """The guess plus ``starts − 1`` Latin-hypercube samples (:func:`sample_starts`), or
    explicit starts checked."""
    if isinstance(starts, int | np.integer):
        if starts < 1:
            raise FitError(f"starts must be at least 1, got {starts}")
        return sample_starts(problem, data, int(starts), seed, concentration)
    x0s = np.atleast_2d(np.asarray(starts, dtype=float))
    if x0s.shape[1] != len(problem.free):
        raise FitError(
            "explicit starts must have one column per free parameter "
            f"({', '.join(problem.free)}), got shape {x0s.shape}"
        )
    return x0s


def result_from(problem, data, x0s, out, sl, settings, timing) -> FitResult:
    """A :class:`FitResult` from the members ``sl`` of a :func:`solve_jobs` output."""
    p, cost, code, steps = out["p"][sl], out["cost"][sl], out["code"][sl], out["steps"][sl]
    p = p[:, : len(problem.free)]  # without the padding of a batch of variants
    status = [_status(c, k, q) for c, k, q in zip(code, cost, p, strict=True)]
    report = StartReport(initial=x0s, params=p, cost=cost, steps=steps, status=tuple(status))
    best = report.best_index()
    if best is None:
        raise FitError(
            f"all {len(status)} starts failed for model {problem.model.name} "
            f"({report.status_summary()}); check the data and bounds, or add starts"
        )
    return FitResult.from_best(
        problem=problem, data=data, report=report, best=best, timing=timing, settings=settings
    )
