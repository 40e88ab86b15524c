"""All-pairs (pairwise) test rows, generated greedily.

A *factor* has a few *levels* (level indices ``0 … n-1``); a *row* gives each factor one level.
:func:`all_pairs` returns rows in which every wanted pair of levels of two different factors
appears at least once — far fewer rows than the full product (about the product of the two
largest level counts, times a slowly growing factor, instead of the product of all).

The greedy rule (after AETG, Cohen et al. 1997, its random candidates seeded so that the rows
are the same on every run): each new row starts from the first pair not yet covered, and gives
every other factor, in turn, the level that covers the most pairs not yet covered together with
the levels already set; ties go to the lowest level (level 0 is the cheap one: an option left
out). Of a few such rows, each filling the factors in another order, the one covering the most
new pairs is kept.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence

Pair = tuple[int, int, int, int]  # (factor i, its level a, factor j > i, its level b)


def pairs_of(row: Sequence[int]) -> set[Pair]:
    """Every pair a row covers."""
    return {(i, row[i], j, row[j]) for i in range(len(row)) for j in range(i + 1, len(row))}


def all_pairs(
    levels: Sequence[int],
    wanted: Callable[[int, int, int, int], bool] = lambda i, a, j, b: True,
    candidates: int = 8,
) -> list[tuple[int, ...]]:
    """Rows covering every pair ``(i, a, j, b)`` (factor ``i`` at level ``a`` with factor
    ``j > i`` at level ``b``) for which ``wanted`` holds; ``levels[i]`` is the number of levels
    of factor ``i``. Each row is the best of ``candidates`` greedy fills (the factors in their
    order, then in seeded shuffled orders). A single factor gives one row per level."""
    n = len(levels)
    if any(k < 1 for k in levels):
        raise ValueError(f"every factor needs a level, got level counts {list(levels)}")
    if n == 1:
        return [(a,) for a in range(levels[0])]
    todo = {
        (i, a, j, b)
        for i in range(n)
        for j in range(i + 1, n)
        for a in range(levels[i])
        for b in range(levels[j])
        if wanted(i, a, j, b)
    }
    rows: list[tuple[int, ...]] = []
    while todo:
        first = min(todo)
        orders = [list(range(n))]
        shuffle = random.Random(len(rows))  # seeded: the same rows on every run
        for _ in range(candidates - 1):
            orders.append(shuffle.sample(range(n), n))
        made = [_fill(first, order, levels, todo) for order in orders]
        done = max(made, key=lambda r: (len(pairs_of(r) & todo), -sum(r)))
        todo -= pairs_of(done)
        rows.append(done)
    return rows


def _fill(
    first: Pair, order: Sequence[int], levels: Sequence[int], todo: set[Pair]
) -> tuple[int, ...]:
    """A row holding the pair ``first``, its other factors set in ``order``, each to the level
    that covers the most pairs of ``todo`` with the levels already set (ties: the lowest)."""
    i0, a0, j0, b0 = first
    row: list[int | None] = [None] * len(levels)
    row[i0], row[j0] = a0, b0
    for k in order:
        if row[k] is not None:
            continue
        best, gain = 0, -1
        for c in range(levels[k]):
            g = sum(
                ((m, row[m], k, c) if m < k else (k, c, m, row[m])) in todo
                for m in range(len(levels))
                if row[m] is not None
            )
            if g > gain:
                best, gain = c, g
        row[k] = best
    return tuple(int(x) for x in row)  # type: ignore[arg-type]
