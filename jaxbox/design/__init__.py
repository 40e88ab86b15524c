"""Experiment design: plan the heating of an identification experiment by differentiating the
Fisher information through the simulator.

:func:`plan` (also ``jaxbox.design_experiment``) finds the heating schedule, within power bounds
(optionally on/off), a comfort band and an energy budget, that minimises a criterion of the
predicted covariance of the estimates (D, A, or the variance of the heat-loss coefficient), and
compares it with PRBS, ROLBS and constant-step (co-heating) schedules of equal length and
energy. :func:`evaluate` predicts the standard deviations of any schedule. See
:mod:`jaxbox.design._fisher` for the criteria and :mod:`jaxbox.design._plan` for the
optimisation.
"""

from ._context import Context as Context
from ._fisher import CRITERIA as CRITERIA
from ._fisher import Setup as Setup
from ._fisher import make_setup as make_setup
from ._plan import Design as Design
from ._plan import baseline_schedules as baseline_schedules
from ._plan import evaluate as evaluate
from ._plan import plan as plan
from ._prior import Prior as Prior
from ._prior import load_prior as load_prior
from ._prior import prior_samples as prior_samples
from ._sequences import SEQUENCES as SEQUENCES
from ._sequences import prbs as prbs
from ._sequences import rolbs as rolbs
from ._sequences import step as step

design_experiment = plan
"""The verb :func:`plan`, as re-exported at the top level (``jaxbox.design_experiment``)."""
