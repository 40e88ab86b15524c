"""The collocation grid: elements, nodes, index maps, and the sparsity of the NLP's Jacobians.

Pure numpy, built once per problem and dataset. The horizon is cut into elements whose
boundaries are the sample instants (each sample interval optionally subdivided into ``subdivide``
equal elements); element ``k`` owns its start node and its ``n_c`` Radau IIA points (the last
one at the element end), and the final instant is one more node.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse

from ._radau import radau_iia


@dataclasses.dataclass(frozen=True)
class _Grid:
    """Elements, nodes and index maps for N samples, ``n_c`` points and ``subdivide``."""

    n_c: int
    subdivide: int
    n_states: int
    t: np.ndarray  # sample times [N]
    h: np.ndarray  # element lengths [K]
    t_nodes: np.ndarray  # node times [M], M = (n_c + 1) K + 1
    win: np.ndarray  # node rows of element k: start, collocation points, next start [K, n_c + 2]
    sample_rows: np.ndarray  # node row of each sample [N]
    colloc_rows: np.ndarray  # node rows of the collocation points [K * n_c]
    frac: np.ndarray  # position of each node within its sample interval, 0 … 1 [M]
    interval: np.ndarray  # sample interval of each node [M]

    @property
    def n_elements(self) -> int:
        return len(self.h)

    @property
    def n_nodes(self) -> int:
        return len(self.t_nodes)

    def interp(self, values: np.ndarray) -> np.ndarray:
        """Sample values [N, q] linearly interpolated onto the nodes [M, q]."""
        i, f = self.interval, self.frac[:, None]
        return values[i] + f * (values[i + 1] - values[i])


def _grid(t: np.ndarray, n_c: int, subdivide: int, n_states: int) -> _Grid:
    rad = radau_iia(n_c)
    n = len(t)
    s = subdivide
    K = (n - 1) * s
    dt = np.diff(t)
    h = np.repeat(dt / s, s)
    sub = np.tile(np.arange(s), n - 1)  # sub-element index within its sample interval
    interval_e = np.repeat(np.arange(n - 1), s)
    starts = t[interval_e] + sub * h
    tau = rad.tau  # 0, c_1 … c_n_c
    # node rows: element k owns rows k (n_c + 1) + 0 … n_c; the final start is row M − 1
    t_nodes = np.concatenate([(starts[:, None] + h[:, None] * tau[None, :]).ravel(), t[-1:]])
    frac = np.concatenate([((sub[:, None] + tau[None, :]) / s).ravel(), [1.0]])
    interval = np.concatenate([np.repeat(interval_e, n_c + 1), [n - 2]])
    base = np.arange(K) * (n_c + 1)
    win = base[:, None] + np.arange(n_c + 2)[None, :]
    colloc_rows = (base[:, None] + 1 + np.arange(n_c)[None, :]).ravel()
    sample_rows = np.arange(n) * s * (n_c + 1)
    return _Grid(
        n_c=n_c,
        subdivide=s,
        n_states=n_states,
        t=t,
        h=h,
        t_nodes=t_nodes,
        win=win,
        sample_rows=sample_rows,
        colloc_rows=colloc_rows,
        frac=frac,
        interval=interval,
    )


@dataclasses.dataclass(frozen=True)
class _Sparsity:
    """Row and column indices of the sparse Jacobians (numpy, built once per problem)."""

    g_rows: np.ndarray
    g_cols: np.ndarray
    j_rows: np.ndarray
    j_cols: np.ndarray
    n_x: int
    n_c: int
    n_r: int


def _sparsity(grid: _Grid, rows: np.ndarray, n_out: int) -> _Sparsity:
    n, nc, K = grid.n_states, grid.n_c, grid.n_elements
    # element constraints: rows n + (k (n_c + 1) + i) n + a, columns win[k, l] n + b
    r = n + (np.arange(K)[:, None, None] * (nc + 1) + np.arange(nc + 1)[None, :, None]) * n
    r = r + np.arange(n)[None, None, :]  # [K, nc+1, n]
    c = grid.win[:, :, None] * n + np.arange(n)[None, None, :]  # [K, nc+2, n]
    g_rows = np.broadcast_to(r[:, :, :, None, None], (K, nc + 1, n, nc + 2, n)).ravel()
    g_cols = np.broadcast_to(c[:, None, None, :, :], (K, nc + 1, n, nc + 2, n)).ravel()
    g_rows = np.concatenate([np.arange(n), g_rows])
    g_cols = np.concatenate([np.arange(n), g_cols])
    R = len(rows)
    jr = np.arange(R)[:, None, None] * n_out + np.arange(n_out)[None, :, None]
    jc = rows[:, None, None] * n + np.arange(n)[None, None, :]
    j_rows = np.broadcast_to(jr, (R, n_out, n)).ravel()
    j_cols = np.broadcast_to(jc, (R, n_out, n)).ravel()
    n_x = grid.n_nodes * n
    return _Sparsity(g_rows, g_cols, j_rows, j_cols, n_x, n_x, R * n_out)


def _assemble(sp: _Sparsity, gx, jx):
    n = sp.n_x
    g_data = np.concatenate([np.ones(sp.g_rows.size - gx.size), np.asarray(gx).ravel()])
    GX = scipy.sparse.csc_matrix((g_data, (sp.g_rows, sp.g_cols)), shape=(n, n))
    j_data = np.asarray(jx).ravel()
    JX = scipy.sparse.csr_matrix((j_data, (sp.j_rows, sp.j_cols)), shape=(sp.n_r, n))
    return GX, JX
