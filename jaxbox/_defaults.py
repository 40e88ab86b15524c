"""The fit's defaults, one copy for Python, the selection and the command line."""

__all__ = ["DEFAULT_STARTS", "DEFAULT_MAX_STEPS", "DEFAULT_HOMOTOPY", "DEFAULT_CONCENTRATION"]

#: starts per fit (the default guess plus Latin-hypercube samples): the default of
#: ``fit_model``, ``fit_many``, ``fit_batch``, ``GreyBox`` cases, ``forward_selection`` and
#: ``jaxbox fit`` / ``jaxbox select``
DEFAULT_STARTS = 8
#: Levenberg–Marquardt iteration cap per start (rejected trials count), shared the same way
DEFAULT_MAX_STEPS = 100
#: observer gains of the continuation every start goes through before the output-error problem
#: itself (see :func:`jaxbox.fit.fit_model`); ``()`` fits the output error from the start
DEFAULT_HOMOTOPY = (0.9, 0.5, 0.2, 0.05)
#: how closely the Latin-hypercube starts cluster around the guess (κ ≥ 0, see
#: :func:`jaxbox.fit.latin_hypercube`): a bounded coordinate is drawn from the beta distribution
#: ``B(1 + κ f, 1 + κ (1 − f))`` over its bounds (``f``: the guess's place in them, in the
#: transform's scale; κ = 4: a standard deviation of at most a fifth of the range). The default
#: of the output-error and maximum-likelihood fits and of the structure search. Closer starts
#: (κ = 16) reach the best cost more often on the twin house and less often on other buildings,
#: and help a local solver from elsewhere as much: ``benchmarks/NOTES.md``, "The starts' spread
#: around the guess"
DEFAULT_CONCENTRATION = 4.0
