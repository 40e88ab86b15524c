# ruff: noqa: E501
"""The peers jaxbox is measured against, on the same data, model and starts.

* :func:`casadi_collocation` — the reference study's route as it is best done today: Radau IIA
  direct collocation (elements at the samples, ``n_c`` points), states and parameters as NLP
  variables, exact first and second derivatives from CasADi, IPOPT; resistances and capacities
  log-scaled, other parameters scaled to their bounds, bounds as variable bounds; the state
  trajectory initialised by an exact simulation with the start's parameters; one start after the
  other (the NLP is built once and reused).
* :func:`scipy_shooting` — the plain Python route: ``scipy.integrate.solve_ivp`` with an implicit
  method (BDF, the constant state Jacobian supplied, steps no longer than a sample interval, inputs
  linear between samples) inside ``scipy.optimize.least_squares`` (trust-region reflective, bounds,
  finite-difference Jacobian), the same parameter scaling; one start after the other.

Both minimise the cost of :func:`jaxbox.fit.fit` (``Σ_k Σ_j (q_j/N) (ŷ_jk − y_jk)²`` at the
samples). Their final parameters are re-evaluated with jaxbox's exact simulation, so every route
is scored by one function. CasADi is an optional dependency (``pip install jaxbox[bench]``).
"""

from __future__ import annotations

import time

import numpy as np

from jaxbox.fit import problem_arrays
from jaxbox.fit._transforms import _LIN, _LOG

__all__ = ["casadi_collocation", "scipy_shooting", "exact_cost", "time_to_best"]


def time_to_best(per_start_s: float, hits: int, n: int, level: float = 0.99) -> float:
    """Expected time to reach the best cost with probability ``level`` by independent starts:
    ``per_start_s × ln(1 − level) / ln(1 − p)``, ``p = hits / n`` the share of starts that
    reached it (one start's time where every start did; ``inf`` where none did)."""
    if n <= 0 or hits <= 0:
        return float("inf")
    if hits >= n:
        return float(per_start_s)
    p = hits / n
    return float(per_start_s * np.log(1.0 - level) / np.log(1.0 - p))


def exact_cost(problem, data, p_free) -> float:
    """The jaxbox cost of free parameters ``p_free`` (exact simulation, the fit's weights)."""
    import jax.numpy as jnp

    t, u, y, sqrt_w = problem_arrays(problem, data)
    fixed = jnp.asarray([v for _, v in problem.fixed], dtype=float)
    ysim = np.asarray(problem.simulate(jnp.asarray(p_free, dtype=float), fixed, t, u))
    r = (ysim - y) * sqrt_w
    return float(np.sum(r * r)) if np.all(np.isfinite(r)) else float("nan")


def _scaling(problem):
    """Per free parameter: ('log', lo, hi) → v = log p; ('lin', lo, hi) → v = (p − lo)/(hi − lo)."""
    out = []
    tr = problem.transform
    for k, lo, hi in zip(tr.kinds, tr.lower, tr.upper, strict=True):
        if k == _LOG:
            out.append(("log", float(lo), float(hi)))
        elif k == _LIN:
            out.append(("lin", float(lo), float(hi)))
        else:
            raise ValueError("the peers support two-sided bounds only")
    return out


def _to_v(scaling, p):
    return np.asarray(
        [
            np.log(x) if k == "log" else (x - lo) / (hi - lo)
            for (k, lo, hi), x in zip(scaling, p, strict=True)
        ]
    )


def _v_bounds(scaling):
    lo = [np.log(a) if k == "log" else 0.0 for k, a, _ in scaling]
    hi = [np.log(b) if k == "log" else 1.0 for k, _, b in scaling]
    return np.asarray(lo), np.asarray(hi)


def _network_matrices(model, theta, *, exp, zeros, stack_rows):
    """A, B of an RC network in any algebra (numpy or CasADi), as jaxbox's ``RCModel.rc_form``."""
    net = model.network
    names = [m.name for m in net.nodes]
    idx = {nm: i for i, nm in enumerate(names)}
    uidx = {u: j for j, u in enumerate(model.inputs)}
    n, m = len(names), len(model.inputs)
    held = [bool(getattr(nd, "constant", False)) for nd in net.nodes]
    G = [[0 for _ in range(n)] for _ in range(n)]
    H = [[0 for _ in range(m)] for _ in range(n)]

    def factor(kind, value):
        if kind == "const":
            return float(value)
        return theta[value] if kind == "param" else 1 - theta[value]

    for e in net.edges:
        r = e.scale * theta[e.R]
        for kind, value in getattr(e, "factors", ()):
            r = r * factor(kind, value)
        g = 1 / r
        i = idx[e.a]
        G[i][i] = G[i][i] - g
        if e.b in idx:
            j = idx[e.b]
            G[j][j] = G[j][j] - g
            G[i][j] = G[i][j] + g
            G[j][i] = G[j][i] + g
        else:
            H[i][uidx[e.b]] = H[i][uidx[e.b]] + g
    for s in net.sources:
        gain = 1.0
        for kind, value in s.gain:
            gain = gain * factor(kind, value)
        i, j = idx[s.node], uidx[s.input]
        H[i][j] = H[i][j] + gain
    A = [[0 if held[i] else G[i][j] / theta[net.nodes[i].C] for j in range(n)] for i in range(n)]
    B = [[0 if held[i] else H[i][j] / theta[net.nodes[i].C] for j in range(m)] for i in range(n)]
    return stack_rows(A), stack_rows(B)


# ---- CasADi + IPOPT direct collocation -------------------------------------------------------------


class _CasadiNLP:
    def __init__(self, problem, data, n_c=3, ipopt_options=None):
        import casadi as ca

        from jaxbox.reference._radau import radau_iia

        self.problem, self.data = problem, data
        model = problem.model
        t, u, y, sqrt_w = problem_arrays(problem, data)
        self.t, self.u, self.y = t, u, y
        n, m = model.n_states, len(model.inputs)
        N = len(t)
        h = float(t[1] - t[0])
        rad = radau_iia(n_c)
        self.scaling = _scaling(problem)
        p = len(problem.free)
        v = ca.SX.sym("v", p)
        theta = dict(problem.fixed)
        for i, (name, (k, lo, hi)) in enumerate(zip(problem.free, self.scaling, strict=True)):
            theta[name] = ca.exp(v[i]) if k == "log" else lo + (hi - lo) * v[i]

        def rows(M):
            return ca.vertcat(
                *[ca.horzcat(*[ca.SX(x) if not isinstance(x, ca.SX) else x for x in r]) for r in M]
            )

        A, B = _network_matrices(model, theta, exp=ca.exp, zeros=None, stack_rows=rows)
        x0 = ca.vertcat(*[theta[nd.T0] for nd in model.network.nodes])
        out_idx = [
            next(i for i, nd in enumerate(model.network.nodes) if nd.output == o)
            for o in model.outputs
        ]
        # one element: start state, n_c point states, inputs at the points -> collocation defects
        P = ca.SX.sym("P", n, n_c + 1)
        Uc = ca.SX.sym("U", m, n_c)
        D = ca.DM(rad.D)
        defect = P @ D.T - h * (A @ P[:, 1:] + B @ Uc)
        element = ca.Function("element", [P, Uc, v], [ca.vec(defect)])
        E = N - 1
        X = ca.SX.sym("X", n, E * n_c)  # the point states, element after element
        starts = ca.horzcat(x0, X[:, n_c - 1 :: n_c][:, : E - 1]) if E > 1 else x0
        # inputs linear between samples, at the collocation times
        Ucoll = np.concatenate(
            [(1 - c) * u[:-1, :, None] + c * u[1:, :, None] for c in rad.c], axis=2
        )  # [E, m, n_c]
        Uall = ca.DM(np.concatenate(list(Ucoll), axis=1))  # m × (E n_c)
        Pall = ca.SX.zeros(n, 0)
        blocks = []
        for k in range(E):
            blocks.append(ca.horzcat(starts[:, k], X[:, k * n_c : (k + 1) * n_c]))
        Pall = ca.horzcat(*blocks)  # n × (E (n_c+1))
        mapped = element.map(E)
        g = mapped(Pall, Uall, ca.repmat(v, 1, E))
        samples = ca.horzcat(x0, X[:, n_c - 1 :: n_c])  # n × N
        ysim = samples[out_idx, :].T
        w = np.broadcast_to(sqrt_w, y.shape)
        r = ca.vec((ysim - ca.DM(y)) * ca.DM(w))
        f = ca.sumsqr(r)
        self.n_x = n * E * n_c
        self.n_c = n_c
        self.rad = rad
        opts = {
            "ipopt.print_level": 0,
            "print_time": False,
            "ipopt.tol": 1e-8,
            "ipopt.max_iter": 3000,
            "ipopt.sb": "yes",
        }
        opts.update(ipopt_options or {})
        nlp = {"x": ca.vertcat(ca.vec(X), v), "f": f, "g": ca.vec(g)}
        self.solver = ca.nlpsol("colloc", "ipopt", nlp, opts)
        self.n_g = int(nlp["g"].shape[0])
        self.vlo, self.vhi = _v_bounds(self.scaling)

    def initial_states(self, p_free):
        """States at the collocation points from an exact simulation with the start's values."""
        import jax.numpy as jnp

        from jaxbox.simulate import simulate_arrays

        theta = dict(self.problem.fixed)
        theta.update(dict(zip(self.problem.free, p_free, strict=True)))
        _, xs = simulate_arrays(self.problem.model, theta, self.t, self.u)
        xs = np.asarray(xs)
        if not np.all(np.isfinite(xs)):
            xs = np.broadcast_to(np.nanmean(self.y), xs.shape).copy()
        pts = [(1 - c) * xs[:-1] + c * xs[1:] for c in self.rad.c]  # [n_c][E, n]
        X = np.stack(pts, axis=1).reshape(-1, xs.shape[1]).T  # n × (E n_c)
        del jnp
        return X.reshape(-1, order="F")

    def solve(self, p_start):
        v0 = np.clip(_to_v(self.scaling, p_start), self.vlo, self.vhi)
        x0 = np.concatenate([self.initial_states(p_start), v0])
        lbx = np.concatenate([np.full(self.n_x, -np.inf), self.vlo])
        ubx = np.concatenate([np.full(self.n_x, np.inf), self.vhi])
        t0 = time.perf_counter()
        sol = self.solver(x0=x0, lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
        wall = time.perf_counter() - t0
        stats = self.solver.stats()
        v = np.asarray(sol["x"]).ravel()[self.n_x :]
        p = np.asarray(
            [
                np.exp(x) if k == "log" else lo + (hi - lo) * x
                for (k, lo, hi), x in zip(self.scaling, v, strict=True)
            ]
        )
        return {
            "p": p,
            "wall_s": wall,
            "status": stats.get("return_status", "?"),
            "success": bool(stats.get("success", False)),
            "iterations": int(stats.get("iter_count", -1)),
            "nlp_cost": float(sol["f"]),
        }


def casadi_collocation(
    problem, data, starts, *, budget_s=None, n_c=3, log=print, ipopt_options=None
):
    """Solve from each start in turn (until ``budget_s`` seconds are spent); one dict per start.
    ``ipopt_options`` (e.g. ``{"ipopt.max_wall_time": 60.0}``) go to IPOPT."""
    t0 = time.perf_counter()
    nlp = _CasadiNLP(problem, data, n_c=n_c, ipopt_options=ipopt_options)
    setup = time.perf_counter() - t0
    log(
        f"    casadi: NLP with {nlp.n_x + len(problem.free)} variables, {nlp.n_g} constraints, setup {setup:.1f} s"
    )
    out = []
    spent = 0.0
    for i, s in enumerate(starts):
        if budget_s is not None and spent > budget_s:
            break
        res = nlp.solve(s)
        res["cost"] = exact_cost(problem, data, res["p"])
        spent += res["wall_s"]
        log(
            f"    casadi start {i}: {res['wall_s']:.1f} s, {res['iterations']} it, {res['status']}, cost {res['cost']:.6g}"
        )
        out.append(res)
    return {"setup_s": setup, "starts": out}


# ---- scipy solve_ivp + least_squares --------------------------------------------------------------


def scipy_shooting(problem, data, starts, *, budget_s=None, method="BDF", log=print):
    """``least_squares`` around ``solve_ivp`` from each start in turn; one dict per start."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import least_squares

    model = problem.model
    t, u, y, sqrt_w = problem_arrays(problem, data)
    scaling = _scaling(problem)
    vlo, vhi = _v_bounds(scaling)
    nodes = model.network.nodes
    out_idx = [next(i for i, nd in enumerate(nodes) if nd.output == o) for o in model.outputs]
    dt = float(t[1] - t[0])
    w = np.broadcast_to(sqrt_w, y.shape)

    def rows(M):
        return np.asarray([[float(x) for x in r] for r in M])

    def residuals(v):
        theta = dict(problem.fixed)
        for name, (k, lo, hi), x in zip(problem.free, scaling, v, strict=True):
            theta[name] = np.exp(x) if k == "log" else lo + (hi - lo) * x
        A, B = _network_matrices(model, theta, exp=np.exp, zeros=None, stack_rows=rows)
        x0 = np.asarray([theta[nd.T0] for nd in nodes])

        def rhs(s, x):
            k = min(int(s // dt), len(t) - 2)
            a = (s - t[k]) / dt
            return A @ x + B @ ((1 - a) * u[k] + a * u[k + 1])

        sol = solve_ivp(
            rhs,
            (t[0], t[-1]),
            x0,
            method=method,
            t_eval=t,
            jac=A,
            rtol=1e-9,
            atol=1e-9,
            max_step=dt,
        )
        if not sol.success or sol.y.shape[1] != len(t):
            return np.full(y.size, 1e3)
        return ((sol.y[out_idx].T - y) * w).ravel()

    out = []
    spent = 0.0
    for i, s in enumerate(starts):
        if budget_s is not None and spent > budget_s:
            break
        v0 = np.clip(_to_v(scaling, s), vlo + 1e-9, vhi - 1e-9)
        t0 = time.perf_counter()
        sol = least_squares(
            residuals, v0, bounds=(vlo, vhi), method="trf", x_scale="jac", diff_step=1e-6
        )
        wall = time.perf_counter() - t0
        p = np.asarray(
            [
                np.exp(x) if k == "log" else lo + (hi - lo) * x
                for (k, lo, hi), x in zip(scaling, sol.x, strict=True)
            ]
        )
        res = {
            "p": p,
            "wall_s": wall,
            "status": sol.message,
            "success": bool(sol.success),
            "iterations": int(sol.nfev),
            "cost": exact_cost(problem, data, p),
        }
        spent += wall
        log(
            f"    scipy start {i}: {wall:.1f} s, {sol.nfev} evaluations, cost {res['cost']:.6g}, {sol.message}"
        )
        out.append(res)
    return {"setup_s": 0.0, "starts": out}
