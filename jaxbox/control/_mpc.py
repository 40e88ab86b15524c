"""Linear model-predictive control of a zone's heating, solved as a linear program (HiGHS).

Over a horizon of ``H`` samples from the current state ``x_0`` (the Kalman filter's estimate),
the heater's power ``q_k`` is constant over each interval ``(t_k, t_{k+1}]`` and the zone
temperature at the samples is affine in the powers::

    T_{k+1} = f_{k+1} + Σ_{i ≤ k} c Φ^{k−i} g q_i,

with ``f`` the free response (heater off; the other inputs, e.g. a weather forecast, with the
fit's hold), ``g = ∫_0^Δt e^{As} ds b`` the response to a unit power over one interval and ``c``
the zone's output row. The program::

    minimise   Σ_k π_k q_k Δt / 3.6e6  +  w Σ_k (s_k + r_k) Δt / 3600
    subject to T_{k+1} + s_k ≥ T_low,k+1,   T_{k+1} − r_k ≤ T_high,k+1,
               q_min ≤ q_k ≤ q_max,   s_k, r_k ≥ 0,

(``π_k`` the energy price per kWh over interval ``k``, ``w`` the price of one kelvin-hour
outside the comfort band ``[T_low, T_high]``) is a linear program, solved by HiGHS
(:func:`scipy.optimize.linprog`). In closed loop only ``q_0`` is applied, the state is updated
by the Kalman filter with the new measurement, and the program is solved again (receding
horizon).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.optimize

from ..fit._problem import FitError

__all__ = ["LinearMPC", "MPCPlan", "KalmanTracker"]


@dataclasses.dataclass(frozen=True, eq=False)
class MPCPlan:
    """The solution of one program.

    Attributes:
        q: the heater's power over each interval [W], ``[H]``.
        T: the predicted zone temperature at the end of each interval [°C], ``[H]``.
        below, above: the predicted violation of the comfort band at those times [K].
        cost: the program's optimum (energy cost plus the price of the violation).
        energy_cost: its energy part. status: HiGHS's message.
    """

    q: np.ndarray
    T: np.ndarray
    below: np.ndarray
    above: np.ndarray
    cost: float
    energy_cost: float
    status: str


@dataclasses.dataclass(frozen=True, eq=False)
class LinearMPC:
    """A linear MPC of the heating of one zone on a fitted model (see the module docstring).

    Attributes:
        system: the discrete model (:meth:`~jaxbox.forecast.StochasticForm.system`) at the
            control step.
        heater: index of the heater in the model's inputs; zone: index of the zone's output.
        horizon: samples ``H``.
        q_max, q_min: the heater's range [W].
        comfort: price of one kelvin-hour outside the band (the currency of the energy price
            per kWh), by default 1 (e.g. 1 € per K·h against prices of 0.1–0.4 € per kWh).
    """

    system: object
    heater: int
    zone: int
    horizon: int
    q_max: float
    q_min: float = 0.0
    comfort: float = 1.0

    @classmethod
    def from_form(
        cls,
        form,
        *,
        horizon: int,
        q_max: float,
        q_min: float = 0.0,
        comfort: float = 1.0,
        step: float | None = None,
        heater: str = "Q_hea",
        zone: str | None = None,
    ) -> LinearMPC:
        """An MPC on a fit's stochastic form (:func:`~jaxbox.forecast.stochastic_form`) at
        ``step`` [s] (default the fit's)."""
        model = form.model
        if heater not in model.inputs:
            raise FitError(f"{model.name} has no heater input {heater!r} ({model.inputs})")
        zone = zone or model.outputs[0]
        if zone not in model.outputs:
            raise FitError(f"{model.name} has no output {zone!r} ({model.outputs})")
        if not (isinstance(horizon, int | np.integer) and horizon >= 1):
            raise FitError(f"horizon must be a whole number of samples ≥ 1, got {horizon!r}")
        if not (np.isfinite(q_max) and np.isfinite(q_min) and q_max > q_min):
            raise FitError(f"the heater's range needs q_min < q_max [W], got {q_min}, {q_max}")
        if not comfort > 0:
            raise FitError(f"comfort (the price of a kelvin-hour) must be > 0, got {comfort}")
        return cls(
            system=form.system(step),
            heater=model.inputs.index(heater),
            zone=model.outputs.index(zone),
            horizon=int(horizon),
            q_max=float(q_max),
            q_min=float(q_min),
            comfort=float(comfort),
        )

    def response(self) -> tuple[np.ndarray, np.ndarray]:
        """``(g [n], M [H, H])``: the state's response to a unit power over one interval, and
        the zone's response ``M[k, i]`` at the end of interval ``k`` to a unit power over
        interval ``i`` (zero for ``i > k``) [K/W]."""
        s = self.system
        g = s.G0[:, self.heater]
        c = s.C[self.zone]
        H = self.horizon
        h = np.empty(H)
        v = g.copy()
        for k in range(H):
            h[k] = c @ v
            v = s.Phi @ v
        M = np.zeros((H, H))
        for k in range(H):
            M[k, : k + 1] = h[k::-1]
        return g, M

    def free_response(self, x0, inputs) -> np.ndarray:
        """The zone temperature [°C] at the end of each interval with the heater off, from the
        state ``x0`` [°C] and the inputs ``inputs`` [H + 1, m] (the heater's column ignored)."""
        s = self.system
        u = np.array(inputs, dtype=float)
        u[:, self.heater] = 0.0
        drive = u[:-1] @ s.G0.T + (u[1:] - u[:-1]) @ s.G1.T
        x = np.asarray(x0, float)
        out = np.empty(self.horizon)
        for k in range(self.horizon):
            x = s.Phi @ x + drive[k]
            out[k] = s.C[self.zone] @ x + s.D[self.zone] @ u[k + 1]
        return out

    def plan(self, x0, inputs, price, lower, upper=None) -> MPCPlan:
        """Solve the program from the state ``x0`` [°C].

        Args:
            x0: the current state (node temperatures) [°C].
            inputs: the model's inputs ``[H + 1, m]`` from now on (the heater's column ignored).
            price: energy price per kWh over each interval ``[H]``.
            lower: the comfort band's lower edge at the end of each interval ``[H]`` [°C].
            upper: its upper edge (default: none).
        """
        H = self.horizon
        inputs = np.asarray(inputs, float)
        if inputs.shape[0] < H + 1:
            raise FitError(
                f"the MPC's horizon is {H} samples but the inputs hold {inputs.shape[0] - 1} "
                "ahead; give inputs over the whole horizon"
            )
        price = _vector(price, H, "price")
        lower = _vector(lower, H, "lower")
        upper = None if upper is None else _vector(upper, H, "upper")
        dt = self.system.dt
        _, M = self.response()
        f = self.free_response(x0, inputs[: H + 1])
        kwh = dt / 3.6e6
        kh = dt / 3600.0
        # variables: q [H], s [H] (below), r [H] (above)
        c = np.concatenate(
            [price * kwh, np.full(H, self.comfort * kh), np.full(H, self.comfort * kh)]
        )
        eye, zero = np.eye(H), np.zeros((H, H))
        # −M q − s ≤ f − lower ;  M q − r ≤ upper − f
        A = [np.hstack([-M, -eye, zero])]
        b = [f - lower]
        if upper is not None:
            A.append(np.hstack([M, zero, -eye]))
            b.append(upper - f)
        bounds = [(self.q_min, self.q_max)] * H + [(0, None)] * H
        bounds += [(0, None) if upper is not None else (0, 0)] * H
        res = scipy.optimize.linprog(
            c, A_ub=np.vstack(A), b_ub=np.concatenate(b), bounds=bounds, method="highs"
        )
        if res.status != 0:
            raise FitError(f"the MPC's linear program failed: {res.message}")
        q = np.clip(res.x[:H], self.q_min, self.q_max)
        T = f + M @ q
        return MPCPlan(
            q=q,
            T=T,
            below=np.clip(lower - T, 0.0, None),
            above=np.zeros(H) if upper is None else np.clip(T - upper, 0.0, None),
            cost=float(res.fun),
            energy_cost=float(price @ q * kwh),
            status=res.message,
        )


def _vector(v, H: int, what: str) -> np.ndarray:
    a = np.broadcast_to(np.asarray(v, float), (H,)) if np.ndim(v) == 0 else np.asarray(v, float)
    if a.shape[0] < H or not np.all(np.isfinite(a[:H])):
        raise FitError(f"{what} must hold {H} finite values (one per interval of the horizon)")
    return np.array(a[:H])


@dataclasses.dataclass
class KalmanTracker:
    """The Kalman filter of a controller, one sample at a time: the heater's power is constant
    over each interval, the other inputs follow the fit's hold.

    Attributes:
        system: the discrete model; heater: index of the heater input.
        m, P: the current filtered mean [°C] and covariance [K²].
    """

    system: object
    heater: int
    m: np.ndarray
    P: np.ndarray

    def predict(self, u0, u1, q: float) -> None:
        """From one sample to the next: inputs ``u0`` and ``u1`` at the two samples (the
        heater's column ignored), the heater at ``q`` [W] over the interval."""
        s = self.system
        u0 = np.array(u0, float)
        u1 = np.array(u1, float)
        u0[self.heater] = u1[self.heater] = 0.0
        d = s.G0 @ u0 + s.G1 @ (u1 - u0) + s.G0[:, self.heater] * q
        self.m = s.Phi @ self.m + d
        P = s.Phi @ self.P @ s.Phi.T + s.Q
        self.P = 0.5 * (P + P.T)

    def update(self, y, u) -> None:
        """The measurement ``y`` [p] (NaN: missing) at the current sample with inputs ``u``."""
        s = self.system
        y = np.asarray(y, float)
        ok = np.isfinite(y)
        if not ok.any():
            return
        C = s.C[ok]
        Rk = np.diag(s.r[ok] ** 2)
        e = y[ok] - C @ self.m - s.D[ok] @ np.asarray(u, float)
        S = C @ self.P @ C.T + Rk
        K = np.linalg.solve(S, C @ self.P).T
        self.m = self.m + K @ e
        IKC = np.eye(len(self.m)) - K @ C
        P = IKC @ self.P @ IKC.T + K @ Rk @ K.T
        self.P = 0.5 * (P + P.T)
