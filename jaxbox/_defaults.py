"""The fit's defaults, one copy for Python, the selection and the command line."""

__all__ = ["DEFAULT_STARTS", "DEFAULT_MAX_STEPS", "DEFAULT_HOMOTOPY"]

#: starts per fit (the default guess plus Latin-hypercube samples): the default of
#: ``fit_model``, ``fit_many``, ``fit_batch``, ``GreyBox`` cases, ``forward_selection`` and
#: ``jaxbox fit`` / ``jaxbox select``
DEFAULT_STARTS = 8
#: Levenberg–Marquardt iteration cap per start (rejected trials count), shared the same way
DEFAULT_MAX_STEPS = 100
#: observer gains of the continuation every start goes through before the output-error problem
#: itself (see :func:`jaxbox.fit.fit_model`); ``()`` fits the output error from the start
DEFAULT_HOMOTOPY = (0.9, 0.5, 0.2, 0.05)
